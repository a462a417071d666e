#!/usr/bin/env bash
# Installs what qota needs, builds everything (library, tools, tests, examples, benchmark) and
# runs the whole test suite.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/install-deps.sh
# The Python extension is built here too (position-independent code), so that the package's pip
# install below reuses these libraries instead of compiling them again.
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release -DQOTA_BUILD_TESTS=ON -DQOTA_BUILD_EXAMPLES=ON \
  -DQOTA_BUILD_BENCH=ON -DQOTA_BUILD_PYTHON=ON -DCMAKE_POSITION_INDEPENDENT_CODE=ON -DQOTA_WERROR=ON > /dev/null
cmake --build build -j2
ctest --test-dir build -j2 --output-on-failure
# The Python package: pip install into a virtual environment, then pytest.
./scripts/python-test.sh
