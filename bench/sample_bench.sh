#!/usr/bin/env bash
# qota sample against gdallocationinfo (GDAL's own point query, nearest pixel) in the same run:
#   1. 1M random points on the bundled Rainier DEM, stdin to stdout (lines per second), and the
#      same through -i/-o files (a pipe should cost nothing more);
#   2. one point on a 40834 x 40834 VRT (the Rainier tile 34 x 34 times, 1.7 G pixels), wall time
#      and peak RSS: qota reads the tile under the point, never the raster;
#   3. 50,000 random points spread over that VRT (a small tile each).
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

# The VRT: the tile repeated 34 x 34 times (the tile's Int16, one SimpleSource per copy).
source bench/bench_common.sh
mosaic 34 > "$work/big.vrt"
point="-110.3 34.7"  # in the middle of the mosaic

echo "sample_bench: $runs runs each, medians (spread = (max - min) / median)"
printf '%-44s %10s %8s %10s\n' "job" "seconds" "spread" "peak MB"
input=$work/points.txt measure "$qota" sample "$dem"
[ "$(grep -c . "$work/out")" = 1000000 ] || { echo "qota did not answer every line"; exit 1; }
q1=$med; printf '%-44s %10s %7s%% %10d\n' "qota sample, 1M points, stdin -> stdout" "$med" "$spread" $((mem / 1024))
input=/dev/null measure "$qota" sample "$dem" -i "$work/points.txt" -o "$work/out_files.txt"
cmp -s "$work/out_files.txt" <(input=$work/points.txt; "$qota" sample "$dem" < "$work/points.txt") || { echo "-i/-o answered otherwise"; exit 1; }
q0=$med; printf '%-44s %10s %7s%% %10d\n' "qota sample, the same with -i/-o files" "$med" "$spread" $((mem / 1024))
input=$work/points.txt measure gdallocationinfo -valonly -geoloc "$dem"
g1=$med; printf '%-44s %10s %7s%% %10d\n' "gdallocationinfo, the same" "$med" "$spread" $((mem / 1024))
echo "$point" > "$work/one.txt"
input=$work/one.txt measure "$qota" sample "$work/big.vrt"
q2=$med; qm=$mem; printf '%-44s %10s %7s%% %10d\n' "qota sample, 1 point, 40834^2 VRT" "$med" "$spread" $((mem / 1024))
input=$work/one.txt measure gdallocationinfo -valonly -geoloc "$work/big.vrt"
g2=$med; printf '%-44s %10s %7s%% %10d\n' "gdallocationinfo, the same" "$med" "$spread" $((mem / 1024))
# 50,000 random points spread over the whole VRT: nearly every point in a tile of its own.
awk 'BEGIN { srand(3); for (i = 0; i < 50000; ++i) printf "%.6f %.6f\n", -122 + 34 * rand(), 13 + 34 * rand() }' > "$work/sparse.txt"
input=$work/sparse.txt measure "$qota" sample "$work/big.vrt"
q3=$med; printf '%-44s %10s %7s%% %10d\n' "qota sample, 50k points over the VRT" "$med" "$spread" $((mem / 1024))
input=$work/sparse.txt measure gdallocationinfo -valonly -geoloc "$work/big.vrt"
g3=$med; printf '%-44s %10s %7s%% %10d\n' "gdallocationinfo, the same" "$med" "$spread" $((mem / 1024))
awk -v q0="$q0" -v q1="$q1" -v g1="$g1" -v q2="$q2" -v g2="$g2" -v qm="$qm" -v q3="$q3" -v g3="$g3" 'BEGIN {
  printf "1M points: qota %.1fx the lines per second of gdallocationinfo (stdin to stdout %.2fx the time of -i/-o)\n", g1 / q1, q1 / q0
  printf "1 point on the VRT: qota takes %.2fx gdallocationinfo'\''s time, %d MB peak\n", q2 / g2, qm / 1024
  printf "50k points over the VRT: qota %.2fx the lines per second of gdallocationinfo\n", g3 / q3 }'
