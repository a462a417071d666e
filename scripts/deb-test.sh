#!/usr/bin/env bash
# The Debian package, as a user gets it: cpack -G DEB in BUILD (default build), then
# apt-get install ./qota_VERSION_ARCH.deb, qota --version, one sample on the bundled DEM, a
# project built with find_package(qota) against /usr, and apt-get remove. Needs root.
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
(cd "$build" && cpack -G DEB > /dev/null)
deb=$(ls "$build"/qota_*_*.deb)
echo "package: $(basename "$deb")"
dpkg-deb -f "$deb" Depends
export DEBIAN_FRONTEND=noninteractive
apt-get install -y -qq "./$deb" > /dev/null
trap 'apt-get remove -y -qq qota > /dev/null' EXIT
/usr/bin/qota --version | head -1
echo "-121.7603 46.8529" | /usr/bin/qota sample data/mt_rainier_90m.tif --mapping geodetic -p 0
work=$(mktemp -d)
cmake -S tests/package -B "$work" -DCMAKE_BUILD_TYPE=Release > /dev/null
cmake --build "$work" -j2 > /dev/null
"$work/core_only"
rm -rf "$work"
