#!/bin/sh
# Builds and runs one fuzz target with the stable toolchain (no nightly, no cargo-fuzz needed):
#   tests/fuzz/fuzz.sh <target> [seconds] [corpus folder]
# e.g. tests/fuzz/fuzz.sh measurements 600 /work/fuzz-corpus/measurements
# CARGO_TARGET_DIR: a target folder of its own (seed it with a copy of a workspace `debug`
# build to reuse the OpenCV/Ceres builds); crashes are written to ./artifacts/<target>/.
# With a nightly toolchain and cargo-fuzz the same targets run with
#   cd tests && cargo +nightly fuzz run <target> <corpus> -- -max_total_time=600 -rss_limit_mb=2048 -timeout=10
set -eu
target="$1"
seconds="${2:-600}"
corpus="${3:-corpus/$target}"
here="$(cd "$(dirname "$0")" && pwd)"
mkdir -p "$corpus" "artifacts/$target"
RUSTC_WRAPPER="$here/rustc-sancov.sh" cargo build --manifest-path "$here/Cargo.toml" --bin "$target"
bin="${CARGO_TARGET_DIR:-$here/target}/debug/$target"
exec nice -n 19 "$bin" "$corpus" -max_total_time="$seconds" -rss_limit_mb=2048 -timeout=10 -max_len=8192 \
    -artifact_prefix="artifacts/$target/" -print_final_stats=1
