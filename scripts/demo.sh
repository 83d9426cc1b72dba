#!/usr/bin/env bash
# The main job: set-up, release build, and `ferrocal demo` on the built-in example.
# Extra arguments go to `ferrocal demo` (e.g. --out DIR).
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/setup.sh
# Rust installed by the set-up lives in ~/.cargo/bin.
export PATH="$HOME/.cargo/bin:$PATH"
cargo run --release --locked -p ferrocal -- demo "$@"
