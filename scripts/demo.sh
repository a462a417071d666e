#!/usr/bin/env bash
# Installs what qota needs, builds the qota command and runs it on the bundled SRTM tile of
# Mount Rainier: the quadtree statistics, then heights under a few points.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/install-deps.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release > /dev/null
cmake --build build -j2 --target qota_cli
dem=data/mt_rainier_90m.tif
echo "== qota info $dem"
build/tools/qota info "$dem" --tree
echo "== qota sample $dem   (lon lat -> height in metres; 'none': no terrain)"
points='-121.7603 46.8529
-121.7353 46.7865
-121.5 46.5
-121.9 46.1'
labels='summit of Mount Rainier
Paradise visitor centre
centre of the tile
south-west of the tile'
paste -d '  ' <(echo "$points") <(echo "$points" | build/tools/qota sample "$dem") <(echo "$labels") |
  awk '{printf "%12s %10s  -> %-20s %s %s %s %s\n", $1, $2, $3, $4, $5, $6, $7}'
echo "== qota shadow $dem (sun from the south-east, 20 degrees up)"
build/tools/qota shadow "$dem" -o build/rainier_shadow.tif -az 135 -alt 20 --png build/rainier_shadow.png
echo "== qota viewshed $dem (what a climber 10 m up at Camp Muir sees, exactly; the Earth's curvature included)"
build/tools/qota viewshed "$dem" --observer -121.7326,46.8356 --oz 10 -o build/rainier_viewshed.tif \
  --png build/rainier_viewshed.png
echo "== qota viewshed $dem --observers data/rainier_lookouts.txt (how many of five ridge-top lookouts see each pixel)"
build/tools/qota viewshed "$dem" --observers data/rainier_lookouts.txt -o build/rainier_lookouts.tif \
  --png build/rainier_lookouts.png
echo "== qota sample data/etopo20.tif --mapping spherical   (the globe as a closed planet under radial gravity;"
echo "   lon lat -> surface radius in metres, and the world point)"
printf '%s\n' '86.925 27.988' '142.2 11.35' '0 90' '180 -52' '-180 -52' |
  build/tools/qota sample data/etopo20.tif --mapping spherical --world -p 1
echo "== qota sample $dem --mapping geodetic -w   (lat lon -> height along the WGS84 normal)"
echo '46.8529 -121.7603' | build/tools/qota sample "$dem" --mapping geodetic -w --world -p 3
echo "== Python: pip install into build-venv (Debian's /usr/bin/python3), heights for a million points"
venv=build-venv
[ -x "$venv/bin/python" ] || /usr/bin/python3 -m venv --system-site-packages "$venv"
"$venv/bin/pip" install --no-build-isolation --no-deps --quiet .
"$venv/bin/python" - "$dem" <<'PY'
import sys, time
import numpy as np
import qota
t = qota.Terrain.from_raster(sys.argv[1])
x, y = np.meshgrid(np.linspace(-121.9, -121.6, 1000), np.linspace(46.7, 46.95, 1000))
start = time.perf_counter()
h = t.heights(x, y)
print(f"qota {qota.__version__}: {h.size} heights in {time.perf_counter() - start:.3f} s, "
      f"highest {np.nanmax(h):.0f} m; summit {t.heights(-121.7603, 46.8529):.1f} m")
PY
