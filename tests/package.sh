#!/usr/bin/env bash
# Installs the build tree BUILD into a temporary prefix and builds and runs a project that finds
# it with find_package(qota 0.2 CONFIG) (tests/package/) and the examples, then checks pkg-config,
# the tool, and qota as a subproject (tests/package/parent/).
#   tests/package.sh BUILD DATA_DIR
set -euo pipefail
build=$1 data=$2
here=$(cd "$(dirname "$0")" && pwd)
work=$(mktemp -d "${TMPDIR:-/tmp}/qota_package.XXXXXX")
trap 'rm -rf "$work"' EXIT
cmake --install "$build" --prefix "$work/prefix" > /dev/null
for f in bin/qota include/qota/terrain.hpp include/qota/version.hpp; do
  [ -e "$work/prefix/$f" ] || { echo "not installed: $f"; exit 1; }
done
config=$(ls "$work"/prefix/lib*/cmake/qota/qotaConfig.cmake)
pc=$(ls "$work"/prefix/lib*/pkgconfig/qota.pc)
cmake -S "$here/package" -B "$work/consumer" -DCMAKE_PREFIX_PATH="$work/prefix" -DCMAKE_BUILD_TYPE=Release > /dev/null
cmake --build "$work/consumer" -j2 > /dev/null
"$work/consumer/core_only"
"$work/consumer/with_rasters" "$data/mt_rainier_90m.tif"
PKG_CONFIG_PATH=$(dirname "$pc") pkg-config --modversion qota
"$work/prefix/bin/qota" --version | head -1
# The examples as a project of their own against the installed package, built and run.
cmake -S "$here/../examples" -B "$work/examples" -DCMAKE_PREFIX_PATH="$work/prefix" -DCMAKE_BUILD_TYPE=Release > /dev/null
cmake --build "$work/examples" -j2 > /dev/null
ctest --test-dir "$work/examples" -j2 --output-on-failure | grep "tests passed"
# As a subproject: configured only (the build is the one above), no build type forced.
cmake -S "$here/package/parent" -B "$work/parent" -DQOTA_SOURCE="$here/.." > /dev/null
if grep -q '^CMAKE_BUILD_TYPE:STRING=.' "$work/parent/CMakeCache.txt"; then
  echo "the subproject set the parent's build type"; exit 1
fi
grep -q '^QOTA_BUILD_TESTS:BOOL=OFF' "$work/parent/CMakeCache.txt" || { echo "tests on in a subproject"; exit 1; }
echo "installed: $(dirname "$config")"
