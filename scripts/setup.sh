#!/usr/bin/env bash
# Installs what a fresh Debian machine lacks to build ferrocal: the C/C++ libraries and tools
# behind the Rust bindings (OpenCV, libclang for its binding generator, cmake and a C++ compiler
# for Ceres and the AprilTag C library). Uses sudo when not root; prints the exact command when
# neither works. Safe to run again: it only installs what is missing.
set -euo pipefail

packages=(libopencv-dev clang libclang-dev cmake pkg-config g++ make git)

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if ((${#missing[@]})); then
  cmd="apt-get update && DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends ${missing[*]}"
  echo "ferrocal setup: installing ${missing[*]}" >&2
  if [[ $(id -u) -eq 0 ]]; then
    bash -c "$cmd"
  elif command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then
    sudo bash -c "$cmd"
  else
    echo "ferrocal setup: cannot install packages (not root, no passwordless sudo). Run as root:" >&2
    echo "  $cmd" >&2
    exit 1
  fi
fi

# Rust: rustup's toolchain in ~/.cargo/bin counts even when that folder is not on PATH yet (the
# calling scripts add it); a machine without any gets it from rustup (curl fetched with apt first
# when missing), or the exact commands are printed.
export PATH="$HOME/.cargo/bin:$PATH"
if ! command -v cargo >/dev/null 2>&1; then
  rustup_cmd="curl --proto '=https' --tlsv1.2 -sSf https://sh.rustup.rs | sh -s -- -y --profile minimal -c clippy,rustfmt"
  if ! command -v curl >/dev/null 2>&1; then
    curl_cmd="apt-get update && DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends curl ca-certificates"
    if [[ $(id -u) -eq 0 ]]; then
      bash -c "$curl_cmd" || true
    elif command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then
      sudo bash -c "$curl_cmd" || true
    fi
  fi
  echo "ferrocal setup: installing Rust with rustup" >&2
  if ! bash -o pipefail -c "$rustup_cmd" || ! command -v cargo >/dev/null 2>&1; then
    echo "ferrocal setup: cannot install Rust. Install it (https://rustup.rs), then run this again:" >&2
    echo "  $rustup_cmd" >&2
    exit 1
  fi
fi
for c in rustfmt clippy; do
  if ! cargo "${c/rustfmt/fmt}" --version >/dev/null 2>&1; then
    if command -v rustup >/dev/null 2>&1; then
      rustup component add "$c"
    else
      echo "ferrocal setup: the Rust component $c is missing: rustup component add $c" >&2
      exit 1
    fi
  fi
done
echo "ferrocal setup: system dependencies present" >&2
