#!/usr/bin/env bash
# Runs a fixed set of commands on the shared data with one ferrocal binary and keeps their
# --json outputs, so that two binaries (before and after a refactor) can be compared:
#
#   scripts/json_identity.sh BINARY OUT_DIR            # e.g. /tmp/base/ferrocal /tmp/json_base
#   scripts/json_identity.sh --compare DIR_A DIR_B     # same files, equal but for timestamps and paths
#
# The data are read from ../shared/data beside the checkout (or $FERROCAL_DATA).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
data="${FERROCAL_DATA:-$root/../shared/data}"

if [[ "${1:-}" == "--compare" ]]; then
    a="$2"
    b="$3"
    status=0
    # Timestamps, durations, temporary paths and the binary's path differ between runs.
    norm() { sed -E -e 's/"[^"]*(time|date|elapsed|seconds|_s|duration)[^"]*": *[^,}]*/"\1": T/g' \
        -e 's#/tmp/[^" ]*##g' -e 's/ in [0-9.]+ s:/ in T s:/' -e 's#"(binary|command_line|argv|version|git)[^"]*": *("[^"]*"|\[[^]]*\])#"\1": X#g' "$1"; }
    for f in "$a"/*.json "$a"/*.stdout; do
        n="$(basename "$f")"
        if [[ ! -f "$b/$n" ]]; then echo "missing in $b: $n"; status=1; continue; fi
        if ! diff -q <(norm "$f") <(norm "$b/$n") >/dev/null; then
            echo "DIFFERS: $n"
            diff <(norm "$f") <(norm "$b/$n") | head -20 || true
            status=1
        else
            echo "same: $n"
        fi
    done
    exit $status
fi

bin="$(realpath "$1")"
out="$(realpath -m "$2")"
mkdir -p "$out"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
cd "$work"
run() { # name, args...: keeps the JSON and the exit status
    local name="$1"
    shift
    set +e
    "$bin" "$@" >"$out/$name.stdout" 2>"$out/$name.stderr"
    echo "$?" >"$out/$name.status"
    set -e
}

run import_ur5 import ur5 --input "$data/ur5_tracker/ur5_grid_train.csv" --out ur5.csv
run calibrate_ur5 calibrate --robot ur5 --measurements ur5.csv --out ur5_cal.json --json "$out/calibrate_ur5.json"
cp ur5_cal.json "$out/ur5_cal_file.json" 2>/dev/null || true
run evaluate_ur5 evaluate --robot ur5 --calibration ur5_cal.json --measurements ur5.csv --json "$out/evaluate_ur5.json"
run diagnose_ur5 diagnose --robot ur5 --measurements ur5.csv --json "$out/diagnose_ur5.json" --out ur5_dg_cal.json
run calibrate_ur5_effects calibrate --robot ur5 --measurements ur5.csv --effects "$out/diagnose_ur5.json" \
    --out ur5_eff_cal.json --json "$out/calibrate_ur5_effects.json"
run calibrate_ur5_list calibrate --robot ur5 --measurements ur5.csv \
    --effects joint_compliance:2,periodic_joint_error:3:180deg,joint_scale_error:1 --out ur5_list_cal.json \
    --json "$out/calibrate_ur5_list.json"
run import_ur10 import ur10 --input "$data/ur10_tracker/Series_B/measurements_joint_configurations.csv" --out ur10b.csv
run calibrate_ur10 calibrate --robot ur10 --measurements ur10b.csv --out ur10_cal.json --json "$out/calibrate_ur10.json"
run diagnose_ur10 diagnose --robot ur10 --measurements ur10b.csv --json "$out/diagnose_ur10.json"
run import_pos import ic-kinematic --input "$data/industrial_calibration/kinematic_calibration" --out pos.csv \
    --test-every 4 --robot-out pos.urdf
run calibrate_pos calibrate --robot pos.urdf --measurements pos.csv --out pos_cal.json --json "$out/calibrate_pos.json"
run diagnose_pos diagnose --robot pos.urdf --measurements pos.csv --json "$out/diagnose_pos.json"
run camera_left camera calibrate --images "$data/opencv_stereo/left*.jpg" --pattern chessboard:9x6:25mm \
    --json "$out/camera_left.json"
run camera_stereo camera stereo --left "$data/opencv_stereo/left*.jpg" --right "$data/opencv_stereo/right*.jpg" \
    --pattern chessboard:9x6:25mm --fix-aspect --json "$out/camera_stereo.json"
run diagnose_left diagnose --images "$data/opencv_stereo/left*.jpg" --pattern chessboard:9x6:25mm \
    --json "$out/diagnose_left.json"
run diagnose_stereo diagnose --images "$data/opencv_stereo/left*.jpg" --images "$data/opencv_stereo/right*.jpg" \
    --pattern chessboard:9x6:25mm --json "$out/diagnose_stereo.json"
for set in test_set_10x10 test_set_charuco; do
    run "import_$set" import ic-handeye --test-every 2 --input "$data/industrial_calibration/$set" --out "$set.csv"
    run "handeye_$set" handeye --images "$data/industrial_calibration/$set/images" --poses "$set.csv" \
        --json "$out/handeye_$set.json"
done
echo "outputs in $out"
