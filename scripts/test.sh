#!/usr/bin/env bash
# The full test suite: installs what the tests need, then runs every test of the
# workspace (unit, property, integration over real pseudo-terminals and loopback TCP,
# interoperability with python-can / python-canopen and tshark).
# Usage: bash scripts/test.sh
set -euo pipefail
cd "$(dirname "$0")/.."
command -v cargo >/dev/null || { echo "cargo is needed: install Rust from your distribution or rustup" >&2; exit 1; }
bash scripts/install-oracles.sh
# Figures the suite measures for scripts/realtime.sh are written afresh by this run.
rm -rf target/realtime/from-suite
# The browser test drives `motus demo` with a 1 ms POWERLINK juggler and headless Chromium on
# the same host: it uses the release binary (a debug build of the whole cell loads a 2-core
# machine enough for the juggler's supervisor to see late cycles).
cargo build --release --locked -p motus
# cargo-nextest runs each test in its own process, several at a time, with the groups and
# time-outs of .config/nextest.toml; it is on this project's machines, and installed here
# otherwise. Doc tests are run by cargo test (nextest does not run them).
if ! cargo nextest --version >/dev/null 2>&1; then
  echo "installing cargo-nextest"
  cargo install cargo-nextest --locked
fi
status=0
cargo nextest run --workspace --locked --no-fail-fast "$@" || status=$?
cargo test --workspace --locked --doc || status=$?
exit "$status"
