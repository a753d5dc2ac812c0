#!/usr/bin/env bash
# The full test suite: installs what the tests need, then runs every test of the
# workspace (unit, property, integration over real pseudo-terminals and loopback TCP,
# interoperability with python-can / python-canopen and tshark).
# Usage: bash scripts/test.sh
set -euo pipefail
cd "$(dirname "$0")/.."
command -v cargo >/dev/null || { echo "cargo is needed: install Rust from your distribution or rustup" >&2; exit 1; }
bash scripts/install-oracles.sh
cargo test --workspace --locked --no-fail-fast "$@"
