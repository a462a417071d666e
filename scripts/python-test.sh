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
"$venv/bin/pip" install --no-build-isolation --no-deps --quiet "$root"
cd /
QOTA_DATA_DIR="$root/data" "$venv/bin/python" -m pytest -q "$root/python/tests"
