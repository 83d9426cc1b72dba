#!/bin/sh
# RUSTC_WRAPPER for `fuzz.sh`: adds libFuzzer's coverage instrumentation (SanitizerCoverage)
# to ferrocal's crates, the fuzz targets and the third-party parsers they call, and leaves every
# other crate as it is. This lets the stable toolchain build the targets in a target folder
# seeded from a workspace build (the OpenCV bindings and Ceres are reused, not rebuilt).
rustc="$1"
shift
name=""
prev=""
for a in "$@"; do
    if [ "$prev" = "--crate-name" ]; then name="$a"; fi
    prev="$a"
done
case "$name" in
    ferrocal_*|measurements|urdf|model_toml|plan_toml|cell_toml|calibration_json|recording|image|\
    toml|toml_parser|toml_datetime|serde_spanned|serde_json|csv|csv_core|roxmltree|png|zune_jpeg|zune_core|\
    tiff|fdeflate|weezl|jpeg_decoder|image_webp|zune_inflate)
        exec "$rustc" "$@" -Cpasses=sancov-module \
            -Cllvm-args=-sanitizer-coverage-level=4 \
            -Cllvm-args=-sanitizer-coverage-inline-8bit-counters \
            -Cllvm-args=-sanitizer-coverage-pc-table \
            -Cllvm-args=-sanitizer-coverage-trace-compares \
            --cfg fuzzing ;;
    *) exec "$rustc" "$@" ;;
esac
