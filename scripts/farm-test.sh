#!/usr/bin/env bash
# Tests of the Python farm driver (python/trayecto_farm): installs it and its dependencies
# (dask.distributed, tqdm, pytest) with pip into a virtual environment under target/, then runs
# pytest against this checkout's trayecto binary. Needs Python >= 3.9 with venv and pip, and PyPI.
# TRAYECTO_SKIP_FARM_TESTS=1 skips them (say so when you do: CI runs them).
set -euo pipefail
cd "$(dirname "$0")/.."

if [[ "${TRAYECTO_SKIP_FARM_TESTS:-}" == 1 ]]; then
    echo "farm driver tests SKIPPED (TRAYECTO_SKIP_FARM_TESTS=1)"
    exit 0
fi
PY="${PYTHON:-python3}"
if ! command -v "$PY" >/dev/null 2>&1; then
    echo "error: the farm driver tests need Python 3.9 or newer ('$PY' not found; set PYTHON=...," >&2
    echo "       or TRAYECTO_SKIP_FARM_TESTS=1 to skip them)" >&2
    exit 1
fi
if ! "$PY" -c 'import sys; sys.exit(sys.version_info < (3, 9))'; then
    echo "error: the farm driver needs Python 3.9 or newer ($("$PY" --version 2>&1))" >&2
    exit 1
fi
VENV=target/farm-venv
if [[ ! -x "$VENV/bin/python" ]]; then
    "$PY" -m venv "$VENV" || {
        echo "error: could not create a virtual environment with $PY -m venv (install python3-venv)" >&2
        exit 1
    }
fi
"$VENV/bin/python" -m pip install -q --disable-pip-version-check -e "python/trayecto_farm[test]" || {
    echo "error: pip could not install the farm driver's dependencies (dask[distributed], tqdm," >&2
    echo "       pytest): is PyPI reachable?" >&2
    exit 1
}
cargo build --profile test --bin trayecto
TRAYECTO_BIN="$(cd "${CARGO_TARGET_DIR:-target}" && pwd)/debug/trayecto" "$VENV/bin/python" -m pytest -q -p no:cacheprovider python/trayecto_farm/tests
