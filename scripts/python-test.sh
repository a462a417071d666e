#!/usr/bin/env bash
# The Python package as a user installs it: a virtual environment on Debian's interpreter
# (/usr/bin/python3, whose site packages hold numpy and GDAL's bindings; a python3 earlier on
# PATH may be another build without them), pip install from the repo root, then pytest on the
# installed package (run from outside the source tree).
#   scripts/python-test.sh [VENV]      (default: build-venv)
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD
./scripts/install-deps.sh
venv=${1:-build-venv}
case $venv in /*) ;; *) venv=$root/$venv ;; esac
[ -x "$venv/bin/python" ] || /usr/bin/python3 -m venv --system-site-packages "$venv"
# The main build, when scripts/test.sh made it with the extension: its libraries are reused.
if [ -z "${QOTA_PYTHON_BUILD_DIR:-}" ] && grep -qs '^QOTA_BUILD_PYTHON:BOOL=ON' "$root/build/CMakeCache.txt"; then
  export QOTA_PYTHON_BUILD_DIR=$root/build
fi
"$venv/bin/pip" install --no-build-isolation --no-deps --quiet "$root"
# The qota tool, for the test that holds qota.shadow to the tool's mask: the main build's, else
# built in the package's CMake folder (its libraries are compiled there already: seconds).
if [ -z "${QOTA_TOOL:-}" ] && [ ! -x "$root/build/tools/qota" ]; then
  pybuild=${QOTA_PYTHON_BUILD_DIR:-$root/build-python}
  case $pybuild in /*) ;; *) pybuild=$root/$pybuild ;; esac
  cmake --build "$pybuild" --target qota_cli -j "${QOTA_JOBS:-2}" >/dev/null
  export QOTA_TOOL=$pybuild/tools/qota
fi
# The stubs (qota/__init__.pyi, qota/dask.pyi) and a typed example against them, under mypy --strict.
(cd "$root/python" && MYPYPATH=. /usr/bin/python3 -m mypy --strict --no-error-summary \
  qota/__init__.pyi qota/dask.pyi tests/typed_example.py)
cd /
# On every core (pytest-xdist; QOTA_JOBS): 64 s to 45 s on two. (Each worker process starts the
# module fixtures' Dask clusters of its own; the dashboard's port goes to the first.)
QOTA_DATA_DIR="$root/data" "$venv/bin/python" -m pytest -q -n "${QOTA_JOBS:-$(nproc)}" \
  -W "ignore:Port 8787 is already in use:UserWarning" "$root/python/tests"
