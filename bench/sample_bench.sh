#!/usr/bin/env bash
# qota sample against gdallocationinfo (GDAL's own point query, nearest pixel) in the same run:
#   1. 1M random points on the bundled Rainier DEM, stdin to stdout (lines per second);
#   2. one point on a 40834 x 40834 VRT (the Rainier tile 34 x 34 times, 1.7 G pixels), wall time
#      and peak RSS: qota reads the tile under the point, never the raster.
# Each timing is the median of RUNS runs (default 5); the spread (max - min over the median) is
# the run-to-run noise. Also checks that qota answered every line.
#   bench/sample_bench.sh [BUILD] [RUNS]
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build} runs=${2:-5}
qota=$build/tools/qota
dem=data/mt_rainier_90m.tif
work=$(mktemp -d "${TMPDIR:-/tmp}/qota_sample_bench.XXXXXX")
trap 'rm -rf "$work"' EXIT

# 1M points on the tile (lon -122..-121, lat 46..47), fixed seed.
awk 'BEGIN { srand(1); for (i = 0; i < 1000000; ++i) printf "%.6f %.6f\n", -122 + rand(), 46 + rand() }' > "$work/points.txt"

# The VRT: the tile repeated 34 x 34 times (SimpleSource per copy, same georeferencing step).
n=34 size=1201
{
  echo "<VRTDataset rasterXSize=\"$((n * size))\" rasterYSize=\"$((n * size))\">"
  echo "  <SRS>EPSG:4326</SRS>"
  echo "  <GeoTransform>-122.000416666666666, 0.000833333333333333, 0, 47.000416666666666, 0, -0.000833333333333333</GeoTransform>"
  echo "  <VRTRasterBand dataType=\"Int16\" band=\"1\">"
  for ((r = 0; r < n; ++r)); do
    for ((c = 0; c < n; ++c)); do
      echo "    <SimpleSource><SourceFilename relativeToVRT=\"0\">$PWD/$dem</SourceFilename><SourceBand>1</SourceBand>"
      echo "      <SrcRect xOff=\"0\" yOff=\"0\" xSize=\"$size\" ySize=\"$size\"/><DstRect xOff=\"$((c * size))\" yOff=\"$((r * size))\" xSize=\"$size\" ySize=\"$size\"/></SimpleSource>"
    done
  done
  echo "  </VRTRasterBand>"
  echo "</VRTDataset>"
} > "$work/big.vrt"
point="-110.3 34.7"  # in the middle of the mosaic

# Median and spread of a command's wall seconds (and of its peak RSS in MB), RUNS times.
measure() {
  local times=() rss=()
  for ((k = 0; k < runs; ++k)); do
    /usr/bin/time -f "%e %M" -o "$work/time" "$@" > "$work/out" 2> "$work/err" < "${input:-/dev/null}" || {
      cat "$work/err"; exit 1; }
    read -r t m < "$work/time"
    times+=("$t") rss+=("$m")
  done
  printf '%s\n' "${times[@]}" | sort -g > "$work/t"
  printf '%s\n' "${rss[@]}" | sort -g > "$work/m"
  local mid=$(((runs + 1) / 2))
  med=$(sed -n "${mid}p" "$work/t") lo=$(head -1 "$work/t") hi=$(tail -1 "$work/t")
  mem=$(sed -n "${mid}p" "$work/m")
  spread=$(awk -v a="$lo" -v b="$hi" -v m="$med" 'BEGIN { printf "%.0f", (m > 0 ? 100 * (b - a) / m : 0) }')
}

echo "sample_bench: $runs runs each, medians (spread = (max - min) / median)"
printf '%-44s %10s %8s %10s\n' "job" "seconds" "spread" "peak MB"
input=$work/points.txt measure "$qota" sample "$dem"
[ "$(grep -c . "$work/out")" = 1000000 ] || { echo "qota did not answer every line"; exit 1; }
q1=$med; printf '%-44s %10s %7s%% %10d\n' "qota sample, 1M points, stdin -> stdout" "$med" "$spread" $((mem / 1024))
input=$work/points.txt measure gdallocationinfo -valonly -geoloc "$dem"
g1=$med; printf '%-44s %10s %7s%% %10d\n' "gdallocationinfo, the same" "$med" "$spread" $((mem / 1024))
echo "$point" > "$work/one.txt"
input=$work/one.txt measure "$qota" sample "$work/big.vrt"
q2=$med; qm=$mem; printf '%-44s %10s %7s%% %10d\n' "qota sample, 1 point, 40834^2 VRT" "$med" "$spread" $((mem / 1024))
input=$work/one.txt measure gdallocationinfo -valonly -geoloc "$work/big.vrt"
g2=$med; printf '%-44s %10s %7s%% %10d\n' "gdallocationinfo, the same" "$med" "$spread" $((mem / 1024))
awk -v q1="$q1" -v g1="$g1" -v q2="$q2" -v g2="$g2" -v qm="$qm" 'BEGIN {
  printf "1M points: qota %.1fx the lines per second of gdallocationinfo\n", g1 / q1
  printf "1 point on the VRT: qota takes %.2fx gdallocationinfo'\''s time, %d MB peak\n", q2 / g2, qm / 1024 }'
