#!/usr/bin/env bash
# Tests of the `trayecto` Python package (PyO3, pyproject.toml at the root): builds it into a
# virtual environment under target/ and runs its pytest suite against this checkout's trayecto
# binary. The package is built with the `test` profile into the same target
# folder as `cargo test`, so the renderer and its dependencies compiled there are reused (only
# pyo3 and the binding crate are compiled). Needs Python >= 3.9 with venv and pip, and PyPI
# (numpy, pytest). TRAYECTO_SKIP_PYTHON_TESTS=1 skips them (say so when you do: CI runs
# them).
set -euo pipefail
cd "$(dirname "$0")/.."

if [[ "${TRAYECTO_SKIP_PYTHON_TESTS:-}" == 1 ]]; then
    echo "Python package tests SKIPPED (TRAYECTO_SKIP_PYTHON_TESTS=1)"
    exit 0
fi
PY="${PYTHON:-python3}"
if ! "$PY" -c 'import sys; sys.exit(sys.version_info < (3, 9))' 2>/dev/null; then
    echo "error: the Python package needs Python 3.9 or newer ('$PY'; set PYTHON=...," >&2
    echo "       or TRAYECTO_SKIP_PYTHON_TESTS=1 to skip its tests)" >&2
    exit 1
fi
TARGET="$(mkdir -p "${CARGO_TARGET_DIR:-target}" && cd "${CARGO_TARGET_DIR:-target}" && pwd)"
VENV="$TARGET/py-venv"
if [[ ! -x "$VENV/bin/python" ]]; then
    "$PY" -m venv "$VENV" || {
        echo "error: could not create a virtual environment with $PY -m venv (install python3-venv)" >&2
        exit 1
    }
fi
"$VENV/bin/python" -m pip install -q --disable-pip-version-check numpy pytest || {
    echo "error: pip could not install numpy and pytest: is PyPI reachable?" >&2
    exit 1
}
# The extension module, built by cargo with the `test` profile (not `maturin build --profile test`,
# which builds through `cargo rustc` and so would make a test harness), and installed into the
# venv as `pip install .` lays the package out: the Python sources and `_trayecto.abi3.so`.
cargo build --profile test -p trayecto-py --features pyo3/extension-module
SITE="$("$VENV/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')"
rm -rf "$SITE/trayecto" "$SITE"/trayecto-*.dist-info
cp -r python/trayecto-py/python/trayecto "$SITE/trayecto"
cp "$TARGET/debug/lib_trayecto.so" "$SITE/trayecto/_trayecto.abi3.so"
cargo build --profile test --bin trayecto
TRAYECTO_BIN="$TARGET/debug/trayecto" "$VENV/bin/python" -m pytest -q -p no:cacheprovider python/trayecto-py/tests
