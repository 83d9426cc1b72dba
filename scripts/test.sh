#!/usr/bin/env bash
# The whole test suite, from a fresh Debian machine: set-up, formatting, lints, tests.
# Expects the shared recordings in ../shared beside the checkout (as CI has them).
set -euo pipefail
cd "$(dirname "$0")/.."
start=$(date +%s)
./scripts/setup.sh
# Rust installed by the set-up lives in ~/.cargo/bin.
export PATH="$HOME/.cargo/bin:$PATH"
# A fresh clone gains nothing from incremental compilation, and its caches take gigabytes of disk.
export CARGO_INCREMENTAL="${CARGO_INCREMENTAL:-0}"
echo "== cargo fmt --check" >&2
cargo fmt --all -- --check
echo "== cargo clippy" >&2
cargo clippy --workspace --all-targets --locked -- -D warnings
# No separate `cargo build`: `cargo test --workspace` builds the ferrocal binary that the
# end-to-end tests run (the tools crate has integration tests), with the same features as the
# tests, so the dependencies are compiled once rather than twice.
echo "== cargo test" >&2
cargo test --workspace --locked
echo "== done in $(( $(date +%s) - start )) s" >&2
