#!/usr/bin/env bash
# The pictures in README.md and docs/, one per tool that draws: shadows, hours of sunlight, a
# viewshed, a cumulative viewshed (each the tool's own --png on a 560 x 500 pixel crop of the
# bundled SRTM tile around Mount Rainier, made with gdal_translate) and the quadtree of the tile.
#   scripts/pictures.sh
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/install-deps.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release > /dev/null
cmake --build build -j2 --target qota_cli
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
dem=$tmp/rainier.tif
gdal_translate -q -srcwin 60 0 560 500 data/mt_rainier_90m.tif "$dem"
q=build/tools/qota
$q shadow "$dem" -az 135 -alt 20 -o "$tmp/shadow.tif" --png docs/rainier_shadow.png -q
$q shadow "$dem" --time 2024-06-21 --tz America/Los_Angeles --hours 4 22 0.25 -o "$tmp/hours.tif" \
  --png docs/rainier_hours.png -q
$q viewshed "$dem" --observer -121.7326,46.8356 --oz 10 -o "$tmp/seen.tif" --png docs/rainier_viewshed.png -q
$q viewshed "$dem" --observers data/rainier_lookouts.txt -o "$tmp/lookouts.tif" --png docs/rainier_lookouts.png -q
$q render-tree data/mt_rainier_90m.tif -o docs/rainier_tree.png --size 800 --max-poly 2850 -q  # (docs/guide/tools.md)
ls -l docs/rainier_*.png
