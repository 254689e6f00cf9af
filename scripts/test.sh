#!/usr/bin/env bash
# The whole test suite, from a fresh clone with only the Rust toolchain installed.
# Installs what the tests need, then runs formatting, lints and every test.
set -euo pipefail
cd "$(dirname "$0")/.."

echo "== cargo fmt --check"
cargo fmt --all -- --check

echo "== cargo clippy -D warnings (the renderer and the Python binding crate)"
cargo clippy --workspace --all-targets -- -D warnings

echo "== Open Image Denoise (run-time library for --denoise and its tests)"
./scripts/install-oidn.sh

echo "== cargo test"
# Library, binary and integration tests, built with the `test` profile (opt-level 3, no LTO: fast
# to compile, fast to run). Benchmarks are type-checked by clippy above; running them is
# `cargo bench`: their timings do not belong in the test suite.
cargo test

echo "== fuzzing (scripts/fuzz.sh: every fuzz target for FUZZ_SECONDS each)"
./scripts/fuzz.sh

echo "== benchmark scoring (bench/compare.py --self-test: synthetic ladders, no renderer)"
python3 bench/compare.py --self-test

echo "== Python package (PyO3: built into a venv with the cargo test build, pytest)"
./scripts/python-test.sh

echo "== farm driver (Python, Dask LocalCluster)"
./scripts/farm-test.sh

echo "== browser end-to-end (web UI)"
./scripts/e2e.sh
