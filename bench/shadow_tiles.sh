#!/usr/bin/env bash
# qota shadow by tiles against the whole raster in memory, in the same run:
#   1. a raster that fits both ways: the Rainier tile 4 x 4 times (4804^2, 23 M pixels, Float32
#      VRT with its nodata), sun at azimuth 315, altitude 30: seconds, pixels per second and peak
#      RSS of the whole-raster run and of the run by tiles within --max-memory 2G, the ratio of
#      their pixels per second, and whether the two rasters are equal pixel for pixel;
#   2. with BIG=1: the tile 34 x 34 times (40834^2, 1.67 G pixels; its whole shadow would need
#      about 350 GiB) by tiles within --max-memory 2G, once: seconds, pixels per second (and their
#      ratio to run 1's whole raster), peak RSS against the 2 GiB allowed.
#   3. with HOURS=1: hours of sunlight on Rainier (2024-06-21, Los Angeles time) from 6 to 20 h
#      and over the whole day, in steps of 15 minutes, whole and by tiles of 256 within
#      --max-memory 400M, once each: seconds, peak RSS, and whether the two are equal pixel for pixel
#      (the whole day's sunrise and sunset steps take long windows toward the Sun).
# Timings are medians of RUNS runs (default 3) with their spread ((max - min) / median).
#   bench/shadow_tiles.sh [BUILD] [RUNS]        BIG=1 bench/shadow_tiles.sh ...  (adds 2; ~15 min)
#   HOURS=1 bench/shadow_tiles.sh ...  (adds 3; ~2 min)
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build} runs=${2:-3}
qota=$build/tools/qota
work=$(mktemp -d "${TMPDIR:-/tmp}/qota_shadow_tiles.XXXXXX")
trap 'rm -rf "$work"' EXIT

source bench/bench_common.sh
mosaic 4 Float32 -32768 > "$work/fits.vrt"

row() { awk -v j="$1" -v s="$2" -v p="$3" -v c="$4" -v m="$5" 'BEGIN { printf "%-46s %8.2f %6s%% %9.2f %8d\n", j, s, p, c / s / 1e6, m }'; }

light=(-az 315 -alt 30)
pixels=$((4804 * 4804))
echo "shadow_tiles: $runs runs each, medians (spread = (max - min) / median)"
printf '%-46s %8s %7s %9s %8s\n' "job" "seconds" "spread" "Mpixels/s" "peak MB"
measure "$qota" shadow "$work/fits.vrt" -o "$work/whole.tif" -q "${light[@]}"
whole=$med; row "whole raster in memory, 4804^2" "$med" "$spread" "$pixels" $((mem / 1024))
measure "$qota" shadow "$work/fits.vrt" -o "$work/tiled.tif" -q "${light[@]}" --max-memory 2G
tiled=$med; row "by tiles, --max-memory 2G, 4804^2" "$med" "$spread" "$pixels" $((mem / 1024))
equal() {
  /usr/bin/python3 - "$1" "$2" << 'EOF' 2>/dev/null || echo "unknown (no Python GDAL)"
import sys
from osgeo import gdal
a, b = (gdal.Open(p).ReadAsArray() for p in sys.argv[1:3])
print("equal pixel for pixel" if a.shape == b.shape and (a == b).all() else "DIFFERENT in %d pixels" % (a != b).sum())
EOF
}
same=$(equal "$work/whole.tif" "$work/tiled.tif")
awk -v w="$whole" -v t="$tiled" -v s="$same" 'BEGIN {
  printf "by tiles: %.2fx the whole raster'\''s pixels per second; the rasters are %s\n", w / t, s }'

if [ "${BIG:-0}" = 1 ]; then
  mosaic 34 Float32 -32768 > "$work/big.vrt"
  big=$((40834 * 40834))
  /usr/bin/time -f "%e %M" -o "$work/time" "$qota" shadow "$work/big.vrt" -o "$work/big.tif" -q "${light[@]}" --max-memory 2G
  read -r t m < "$work/time"
  row "by tiles, --max-memory 2G, 40834^2 (once)" "$t" "-" "$big" $((m / 1024))
  awk -v w="$whole" -v t="$t" -v b="$big" -v c="$pixels" -v m="$m" 'BEGIN {
    printf "40834^2 by tiles: %.2fx the 4804^2 whole raster'\''s pixels per second; peak %.0f MB of the 2048 allowed\n", (b / t) / (c / w), m / 1024 }'
fi

if [ "${HOURS:-0}" = 1 ]; then
  once() {  # seconds and peak MB of one run
    /usr/bin/time -f "%e %M" -o "$work/time" "$@" > /dev/null
    read -r t m < "$work/time"
    echo "$t $((m / 1024))"
  }
  day=(--time 2024-06-21 --tz America/Los_Angeles -q)
  for span in "6 20" "0 24"; do
    read -r tw mw < <(once "$qota" shadow data/mt_rainier_90m.tif -o "$work/hw.tif" "${day[@]}" --hours $span 0.25)
    read -r tt mt < <(once "$qota" shadow data/mt_rainier_90m.tif -o "$work/ht.tif" "${day[@]}" --hours $span 0.25 \
      --tile-size 256 --max-memory 400M)
    printf 'hours %-5s on Rainier: whole %6.2f s %5d MB; tiles of 256 in 400M %6.2f s %5d MB; %.1fx the time; %s\n' \
      "$span" "$tw" "$mw" "$tt" "$mt" "$(awk -v a="$tt" -v b="$tw" 'BEGIN { print a / b }')" "$(equal "$work/hw.tif" "$work/ht.tif")"
  done
fi
