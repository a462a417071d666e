#!/usr/bin/env bash
# Installs the build tree BUILD into a temporary prefix and builds and runs a project that finds
# it with find_package(qota 0.2 CONFIG) (tests/package/) and the examples, then checks pkg-config,
# the tool, and qota as a subproject (tests/package/parent/).
#   tests/package.sh BUILD DATA_DIR
# A shared build (BUILD_SHARED_LIBS=ON) is checked for its SONAMEs and for the installed tool
# finding its libraries without LD_LIBRARY_PATH. QOTA_CONSUMER_FLAGS: compiler and linker flags
# for the projects built against the install (a sanitizer build's -fsanitize=...).
set -euo pipefail
build=$1 data=$2
flags=(-DCMAKE_CXX_FLAGS="${QOTA_CONSUMER_FLAGS:-}" -DCMAKE_EXE_LINKER_FLAGS="${QOTA_CONSUMER_FLAGS:-}")
here=$(cd "$(dirname "$0")" && pwd)
work=$(mktemp -d "${TMPDIR:-/tmp}/qota_package.XXXXXX")
trap 'rm -rf "$work"' EXIT
cmake --install "$build" --prefix "$work/prefix" > /dev/null
for f in bin/qota include/qota/terrain.hpp include/qota/version.hpp; do
  [ -e "$work/prefix/$f" ] || { echo "not installed: $f"; exit 1; }
done
config=$(ls "$work"/prefix/lib*/cmake/qota/qotaConfig.cmake)
if grep -q '^BUILD_SHARED_LIBS:BOOL=ON' "$build/CMakeCache.txt"; then
  version=$(sed -n 's/^CMAKE_PROJECT_VERSION:STATIC=\([0-9]*\.[0-9]*\).*/\1/p' "$build/CMakeCache.txt")
  for lib in qota qota_core qota_coords; do
    so=$(ls "$work"/prefix/lib*/lib$lib.so)
    readelf -d "$so" | grep -q "SONAME.*\[lib$lib.so.$version\]" || { echo "$so: SONAME is not lib$lib.so.$version"; exit 1; }
  done
  ldd "$work/prefix/bin/qota" | grep -q "libqota.so.$version => $work/prefix" ||
    { echo "the installed qota does not load the installed libqota.so.$version"; exit 1; }
  echo "shared: SONAME lib*.so.$version, the tool loads them from the prefix"
fi
pc=$(ls "$work"/prefix/lib*/pkgconfig/qota.pc)
cmake -S "$here/package" -B "$work/consumer" -DCMAKE_PREFIX_PATH="$work/prefix" -DCMAKE_BUILD_TYPE=Release "${flags[@]}" > /dev/null
cmake --build "$work/consumer" -j2 > /dev/null
"$work/consumer/core_only"
"$work/consumer/with_rasters" "$data/mt_rainier_90m.tif"
PKG_CONFIG_PATH=$(dirname "$pc") pkg-config --modversion qota
"$work/prefix/bin/qota" --version | head -1
# The examples as a project of their own against the installed package, built and run. (Not in
# a sanitizer build, which runs them in its own tree: the release build's run of this script
# covers them, and the sanitizers' time is CI's longest stage.)
if [ -z "${QOTA_CONSUMER_FLAGS:-}" ]; then
  cmake -S "$here/../examples" -B "$work/examples" -DCMAKE_PREFIX_PATH="$work/prefix" -DCMAKE_BUILD_TYPE=Release > /dev/null
  cmake --build "$work/examples" -j2 > /dev/null
  ctest --test-dir "$work/examples" -j2 --output-on-failure | grep "tests passed"
else
  echo "examples: run in the build tree"
fi
# As a subproject: configured only (the build is the one above), no build type forced.
cmake -S "$here/package/parent" -B "$work/parent" -DQOTA_SOURCE="$here/.." > /dev/null
if grep -q '^CMAKE_BUILD_TYPE:STRING=.' "$work/parent/CMakeCache.txt"; then
  echo "the subproject set the parent's build type"; exit 1
fi
grep -q '^QOTA_BUILD_TESTS:BOOL=OFF' "$work/parent/CMakeCache.txt" || { echo "tests on in a subproject"; exit 1; }
echo "installed: $(dirname "$config")"
# COMPONENTS core: configured, built and run with the full library's dependencies hidden from
# find_package; an unknown component is refused.
hide=()
for p in GDAL PROJ glm assimp date; do hide+=(-DCMAKE_DISABLE_FIND_PACKAGE_$p=ON); done
cmake -S "$here/package/core" -B "$work/core" -DCMAKE_PREFIX_PATH="$work/prefix" -DCMAKE_BUILD_TYPE=Release \
  --no-warn-unused-cli "${hide[@]}" "${flags[@]}" > /dev/null
cmake --build "$work/core" -j2 > /dev/null
"$work/core/core_component"
mkdir -p "$work/nosuch"
printf 'cmake_minimum_required(VERSION 3.25)\nproject(n LANGUAGES CXX)\nfind_package(qota CONFIG REQUIRED COMPONENTS nosuch)\n' \
  > "$work/nosuch/CMakeLists.txt"
if cmake -S "$work/nosuch" -B "$work/nosuch/build" -DCMAKE_PREFIX_PATH="$work/prefix" > "$work/nosuch.log" 2>&1; then
  echo "find_package(qota COMPONENTS nosuch) was accepted"; exit 1
fi
grep -q "no component 'nosuch'" "$work/nosuch.log" || { cat "$work/nosuch.log"; exit 1; }
echo "COMPONENTS core: found and linked without GDAL, PROJ, GLM, Assimp or date; nosuch refused"
# qota.pc from a moved install: its prefix follows the file.
cp -r "$work/prefix" "$work/moved"
moved_pc=$(ls "$work"/moved/lib*/pkgconfig/qota.pc)
inc=$(PKG_CONFIG_PATH=$(dirname "$moved_pc") pkg-config --variable=includedir qota)
[ -e "$inc/qota/terrain.hpp" ] || { echo "qota.pc of a moved install names $inc"; exit 1; }
libdir=$(PKG_CONFIG_PATH=$(dirname "$moved_pc") pkg-config --variable=libdir qota-core)
# (the consumer flags: a sanitizer build's runtime; the run path: a shared build's libraries)
# shellcheck disable=SC2046,SC2086
c++ ${QOTA_CONSUMER_FLAGS:-} -std=c++20 -O1 "$here/package/core_only.cpp" -o "$work/pc_core" -Wl,-rpath,"$libdir" \
  $(PKG_CONFIG_PATH=$(dirname "$moved_pc") pkg-config --cflags --libs qota-core)
"$work/pc_core"
echo "qota.pc, qota-core.pc: a moved install's paths; qota-core builds a program"
