"""qota's Python heights against the same triangle interpolation written in numpy alone, and
against the library's C++ batch on the same points (build/bench/batch_bench, when built).

    build-venv/bin/python python/bench/bench_numpy.py [DEM] [POINTS]

Both sides answer the same points on the same raster (GDAL reads it for numpy): pixel centres
joined into two triangles a cell, split from the top-left to the bottom-right centre, nodata
cells holes. Prints each side's median of 7 runs with the spread (min to max, the run-to-run
noise), the ratio, and the largest difference between the answers (rounding only).
"""
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from osgeo import gdal

import qota

dem = sys.argv[1] if len(sys.argv) > 1 else str(Path(__file__).resolve().parents[2] / "data" / "mt_rainier_90m.tif")
n = int(sys.argv[2]) if len(sys.argv) > 2 else 1_000_000

ds = gdal.Open(dem)
band = ds.GetRasterBand(1)
z = band.ReadAsArray().astype(np.float64)
nodata = band.GetNoDataValue()
if nodata is not None:
    z[z == nodata] = np.nan
gt = ds.GetGeoTransform()
rows, cols = z.shape
rng = np.random.default_rng(1)
# Points between the outermost pixel centres (the numpy side has no outer half pixel).
c = rng.uniform(0.5, cols - 0.5, n)
r = rng.uniform(0.5, rows - 0.5, n)
x = gt[0] + c * gt[1] + r * gt[2]
y = gt[3] + c * gt[4] + r * gt[5]


def numpy_heights(x, y):
    # World to pixel-centre coordinates (a north-up raster), then the cell and the triangle.
    fc = (x - gt[0]) / gt[1] - 0.5
    fr = (y - gt[3]) / gt[5] - 0.5
    c0 = np.clip(np.floor(fc).astype(np.int64), 0, cols - 2)
    r0 = np.clip(np.floor(fr).astype(np.int64), 0, rows - 2)
    fx, fy = fc - c0, fr - r0
    tl, tr = z[r0, c0], z[r0, c0 + 1]
    bl, br = z[r0 + 1, c0], z[r0 + 1, c0 + 1]
    lower = fy >= fx  # (TL, BL, BR) below the diagonal, rows running down
    return np.where(lower, tl + fy * (bl - tl) + fx * (br - bl), tl + fx * (tr - tl) + fy * (br - tr))


def timed(f):
    runs = []
    for _ in range(7):
        start = time.perf_counter()
        out = f()
        runs.append(time.perf_counter() - start)
    return out, np.median(runs), min(runs), max(runs)


start = time.perf_counter()
terrain = qota.Terrain.from_raster(dem)
build = time.perf_counter() - start
want, tn, tn0, tn1 = timed(lambda: numpy_heights(x, y))
got, tq, tq0, tq1 = timed(lambda: terrain.heights(x, y))
both = ~np.isnan(want) & ~np.isnan(got)
print(f"{Path(dem).name}: {rows} x {cols}, {n} random points; qota load and index {build:.2f} s")
print(f"numpy alone  {tn:.4f} s  ({tn0:.4f} to {tn1:.4f})  {n / tn / 1e6:6.1f} M points/s")
print(f"qota         {tq:.4f} s  ({tq0:.4f} to {tq1:.4f})  {n / tq / 1e6:6.1f} M points/s")
print(f"qota / numpy: {tn / tq:.1f}x the points per second")
print(f"answers: {np.count_nonzero(both)} both, {np.count_nonzero(np.isnan(want) != np.isnan(got))} differ in "
      f"having terrain (on hole outlines), largest height difference {np.max(np.abs(want[both] - got[both])):.2e}")

cxx = Path(os.environ.get("QOTA_BATCH_BENCH", Path(__file__).resolve().parents[2] / "build" / "bench" / "batch_bench"))
if cxx.exists():
    with tempfile.TemporaryDirectory() as folder:
        points = Path(folder) / "points.bin"
        np.concatenate([x, y]).astype(np.float64).tofile(points)
        line = subprocess.run([str(cxx), dem, str(points)], check=True, capture_output=True, text=True).stdout
    tc, tc0, tc1 = (float(v) for v in line.split()[1:])
    print(f"C++ batch    {tc:.4f} s  ({tc0:.4f} to {tc1:.4f})  {n / tc / 1e6:6.1f} M points/s")
    print(f"Python / C++: {tq / tc:.2f}x the time")
