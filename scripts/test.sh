#!/usr/bin/env bash
# The whole test suite, from a fresh Debian machine: set-up, formatting, lints, tests.
# Expects the shared recordings in ../shared beside the checkout (as CI has them).
set -euo pipefail
cd "$(dirname "$0")/.."
start=$(date +%s)
./scripts/setup.sh
# Rust installed by the set-up lives in ~/.cargo/bin.
export PATH="$HOME/.cargo/bin:$PATH"
echo "== cargo fmt --check" >&2
cargo fmt --all -- --check
echo "== cargo clippy" >&2
cargo clippy --workspace --all-targets --locked -- -D warnings
echo "== cargo build (the binary the end-to-end tests run)" >&2
cargo build --workspace --bins --locked
echo "== cargo test" >&2
cargo test --workspace --locked
echo "== done in $(( $(date +%s) - start )) s" >&2
