#!/usr/bin/env bash
# The main job: set-up, release build, and `ferrocal demo` on the built-in example.
# Extra arguments go to `ferrocal demo` (e.g. --out DIR).
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/setup.sh
cargo run --release --locked -p ferrocal -- demo "$@"
