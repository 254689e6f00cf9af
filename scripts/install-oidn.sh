#!/usr/bin/env bash
# Installs Intel Open Image Denoise for `trayecto render --denoise`: the PyPI wheel `pyoidn`
# (which ships libOpenImageDenoise.so and its CPU device) into a virtual environment under
# target/, where trayecto looks for it. Trayecto loads the library at run time, so the build never
# needs it. Needs Python >= 3.9 with venv and pip, and PyPI. Prints the library's path.
# Elsewhere: `--oidn PATH` or TRAYECTO_OIDN=PATH point trayecto at any libOpenImageDenoise.so.
set -euo pipefail
cd "$(dirname "$0")/.."

# The version the denoising code and its tests were written against (OIDN 2.x C API).
PYOIDN_VERSION=2.5.1.0
PY="${PYTHON:-python3}"
if ! command -v "$PY" >/dev/null 2>&1; then
    echo "error: installing OIDN needs Python 3.9 or newer ('$PY' not found; set PYTHON=...)" >&2
    exit 1
fi
VENV="${CARGO_TARGET_DIR:-target}/oidn-venv"
LIB_GLOB="$VENV/lib/python3*/site-packages/pyoidn/oidn/lib/libOpenImageDenoise.so"
# shellcheck disable=SC2086
if ! ls $LIB_GLOB >/dev/null 2>&1; then
    if [[ ! -x "$VENV/bin/python" ]]; then
        "$PY" -m venv "$VENV" || {
            echo "error: could not create a virtual environment with $PY -m venv (install python3-venv)" >&2
            exit 1
        }
    fi
    # --no-deps: only the wheel's shared libraries are used, not its Python bindings (numpy).
    "$VENV/bin/python" -m pip install -q --disable-pip-version-check --no-deps \
        "pyoidn==$PYOIDN_VERSION" || {
        echo "error: pip could not install pyoidn==$PYOIDN_VERSION: is PyPI reachable?" >&2
        exit 1
    }
fi
# shellcheck disable=SC2086
ls $LIB_GLOB
