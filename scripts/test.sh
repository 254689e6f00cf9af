#!/usr/bin/env bash
# The whole test suite, from a fresh clone with only the Rust toolchain installed.
# Installs what the tests need, then runs formatting, lints and every test.
set -euo pipefail
cd "$(dirname "$0")/.."

echo "== cargo fmt --check"
cargo fmt --all -- --check

echo "== cargo clippy -D warnings"
cargo clippy --release --all-targets -- -D warnings

echo "== cargo test"
cargo test --release --all-targets

echo "== browser end-to-end (web UI)"
./scripts/e2e.sh
