#!/usr/bin/env bash
# qota viewshed against gdal_viewshed and GRASS r.viewshed (Debian's grass-core, which it
# installs) in the same run, on a 2000 x 2000 DEM of 30 m pixels (the Rainier tile warped to UTM
# 10N, bilinear), observer 2 m up at a pixel centre, flat (no curvature: gdal_viewshed -cc 0,
# r.viewshed without -c, qota --flat), the whole raster and within 10 km; then each tool's
# default with curvature (qota exact on WGS84, gdal_viewshed's correction), timed. Times are
# medians of RUNS runs (default 3) with their spread ((max - min) / median). Agreement: the pixels each
# tool marks otherwise than qota (exact on the triangulated terrain: tests/test_viewshed.cpp),
# among the pixels with data within range, and how many each marks visible.
#   bench/viewshed_bench.sh [BUILD] [RUNS]
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build} runs=${2:-3}
qota=$build/tools/qota
work=$(mktemp -d "${TMPDIR:-/tmp}/qota_viewshed_bench.XXXXXX")
trap 'rm -rf "$work"' EXIT
source bench/bench_common.sh

dem=$work/dem.tif
gdalwarp -q -t_srs EPSG:32610 -tr 30 30 -te 565000 5150000 625000 5210000 -r bilinear -ot Float32 \
  -dstnodata -32768 data/mt_rainier_90m.tif "$dem"
x=593015 y=5185985  # the centre of pixel (934, 800), on the mountain's south-west flank
# GRASS (Debian's grass-core) for r.viewshed, installed here as the README's figures need it; a
# machine that cannot install it runs the rest and says so.
./scripts/install-deps.sh grass-core > /dev/null 2>&1 || echo "viewshed_bench: grass-core not installed: no r.viewshed figures" >&2
grass=$(command -v grass || true)

echo "viewshed_bench: 2000 x 2000 pixels of 30 m, observer ($x, $y) 2 m up; $runs runs each, medians"
printf '%-50s %8s %8s %8s\n' "job" "seconds" "spread" "peak MB"
declare -A secs
for md in 0 10000; do
  label=$([ "$md" = 0 ] && echo "whole raster" || echo "within 10 km")
  qmd=() gmd=() rmd=-1
  [ "$md" != 0 ] && qmd=(--md "$md") gmd=(-md "$md") rmd=$md
  measure "$qota" viewshed "$dem" --observer "$x,$y" --oz 2 --flat "${qmd[@]}" -o "$work/qota_$md.tif" -q
  secs[qota_$md]=$med
  printf '%-50s %8s %7s%% %8d\n' "qota viewshed, $label" "$med" "$spread" $((mem / 1024))
  # Once more, to say how the pixels were decided (the sweep, or its exact fallback one by one).
  "$qota" viewshed "$dem" --observer "$x,$y" --oz 2 --flat "${qmd[@]}" -o "$work/qota_$md.tif" |
    sed -n 's/^decided: /    decided: /p'
  # The same viewshed one line of sight per pixel through the quadtree (the way before the
  # sweep), once: its answers must be the sweep's, pixel for pixel.
  saved=$runs runs=1
  measure "$qota" viewshed "$dem" --observer "$x,$y" --oz 2 --flat "${qmd[@]}" --per-pixel \
    -o "$work/perpixel_$md.tif" -q
  runs=$saved
  printf '%-50s %8s %8s %8d\n' "qota viewshed --per-pixel, $label" "$med" "(once)" $((mem / 1024))
  measure gdal_viewshed -q -ox "$x" -oy "$y" -oz 2 -cc 0 -vv 255 -iv 0 -ov 64 "${gmd[@]}" "$dem" "$work/gdal_$md.tif"
  secs[gdal_$md]=$med
  printf '%-50s %8s %7s%% %8d\n' "gdal_viewshed, $label" "$med" "$spread" $((mem / 1024))
  # With curvature: qota's default (the DEM on WGS84 over EGM96, straight lines in ECEF, each
  # line of sight walked over the squares under it), once more through the quadtree (its answers
  # must be the walk's), and gdal_viewshed's default (-cc 0.85714: a parabolic drop, refraction in).
  measure "$qota" viewshed "$dem" --observer "$x,$y" --oz 2 "${qmd[@]}" -o "$work/curved_$md.tif" -q
  secs[curved_$md]=$med
  printf '%-50s %8s %7s%% %8d\n' "qota viewshed on WGS84 (default), $label" "$med" "$spread" $((mem / 1024))
  saved=$runs runs=1
  measure "$qota" viewshed "$dem" --observer "$x,$y" --oz 2 "${qmd[@]}" --per-pixel -o "$work/curvedpp_$md.tif" -q
  runs=$saved
  printf '%-50s %8s %8s %8d\n' "qota viewshed on WGS84 --per-pixel, $label" "$med" "(once)" $((mem / 1024))
  measure gdal_viewshed -q -ox "$x" -oy "$y" -oz 2 -vv 255 -iv 0 -ov 64 "${gmd[@]}" "$dem" "$work/gdalcc_$md.tif"
  secs[gdalcc_$md]=$med
  printf '%-50s %8s %7s%% %8d\n' "gdal_viewshed, its curvature, $label" "$med" "$spread" $((mem / 1024))
  if [ -n "$grass" ]; then
    # GRASS needs a project: made once in the scratch folder, the DEM imported; r.viewshed alone timed.
    [ -d "$work/grass" ] || grass -c "$dem" -e "$work/grass" > /dev/null 2>&1
    grass "$work/grass/PERMANENT" --exec r.in.gdal -o input="$dem" output=dem --quiet > /dev/null 2>&1 || true
    grass "$work/grass/PERMANENT" --exec g.region raster=dem > /dev/null 2>&1
    measure grass "$work/grass/PERMANENT" --exec r.viewshed -b --overwrite --quiet input=dem output=seen \
      coordinates="$x,$y" observer_elevation=2 target_elevation=0 max_distance="$rmd" memory=2000
    secs[grass_$md]=$med
    printf '%-50s %8s %7s%% %8d\n' "r.viewshed (with GRASS's start-up), $label" "$med" "$spread" $((mem / 1024))
    grass "$work/grass/PERMANENT" --exec r.out.gdal --quiet -f input=seen output="$work/grass_$md.tif" type=Byte \
      nodata=200 > /dev/null 2>&1
  fi
done

echo
echo "cells per second against gdal_viewshed's (same DEM, same observer): whole raster $(
  awk -v q="${secs[qota_0]}" -v g="${secs[gdal_0]}" 'BEGIN { printf "%.2fx", g / q }'), within 10 km $(
  awk -v q="${secs[qota_10000]}" -v g="${secs[gdal_10000]}" 'BEGIN { printf "%.2fx", g / q }')"
echo "with curvature (qota exact on WGS84, gdal_viewshed's correction): whole raster $(
  awk -v q="${secs[curved_0]}" -v g="${secs[gdalcc_0]}" 'BEGIN { printf "%.2fx", g / q }'), within 10 km $(
  awk -v q="${secs[curved_10000]}" -v g="${secs[gdalcc_10000]}" 'BEGIN { printf "%.2fx", g / q }')"
echo
echo "agreement with the exact rule (pixels with data within range):"
/usr/bin/python3 - "$work" <<'EOF'
import sys, os
import numpy as np
from osgeo import gdal
work = sys.argv[1]
def read(name, like=None):
    """A raster's band 1; `like`: a reference name whose grid it is cut out of (gdal_viewshed
    writes only the window of its distance): the window placed on that grid, the rest 64."""
    path = os.path.join(work, name)
    if not os.path.exists(path):
        return None
    ds = gdal.Open(path)
    a = ds.GetRasterBand(1).ReadAsArray()
    if like is None:
        return a
    ref = gdal.Open(os.path.join(work, like))
    g, r = ds.GetGeoTransform(), ref.GetGeoTransform()
    col, row = round((g[0] - r[0]) / r[1]), round((g[3] - r[3]) / r[5])
    full = np.full((ref.RasterYSize, ref.RasterXSize), 64, dtype=a.dtype)
    full[row:row + a.shape[0], col:col + a.shape[1]] = a
    return full
for md in ("0", "10000"):
    q = read(f"qota_{md}.tif")
    inside = (q == 255) | (q == 0)
    print(f"  {'whole raster' if md == '0' else 'within 10 km'}: {inside.sum()} pixels, qota (exact) marks "
          f"{(q[inside] == 255).sum()} visible")
    p = read(f"perpixel_{md}.tif")
    print(f"    qota --per-pixel (one line of sight a pixel through the quadtree): differs from the sweep on "
          f"{(p != q).sum()} pixels of all {q.size}")
    c, cp = read(f"curved_{md}.tif"), read(f"curvedpp_{md}.tif")
    print(f"    on the ellipsoid: qota marks {(c == 255).sum()} visible; --per-pixel differs from the walk on "
          f"{(c != cp).sum()} pixels of all {c.size}")
    for tool, visible in (("gdal_viewshed", 255), ("r.viewshed", 1)):
        a = read(f"{'gdal' if tool == 'gdal_viewshed' else 'grass'}_{md}.tif", f"qota_{md}.tif")
        if a is None:
            continue
        seen = a[inside] == visible
        exact = q[inside] == 255
        print(f"    {tool}: marks {seen.sum()} visible; differs on {(seen != exact).sum()} "
              f"({(seen & ~exact).sum()} visible where hidden, {(~seen & exact).sum()} hidden where visible)")
EOF
