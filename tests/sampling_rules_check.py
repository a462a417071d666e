#!/usr/bin/python3
"""qota sample -r nearest|bilinear|cubic against GDAL and against GDAL's documented kernels.

nearest is compared with gdallocationinfo's own output; bilinear and cubic with a numpy
computation of GDAL's definitions (pixel centres, indices clamped at the edges, a void among the
four bilinear pixels leaves no value, cubic: Keys' kernel with a = -0.5, voids left out and the
weights renormalised, a raster narrower than the kernel taking the next smaller one), written here
from the documentation, not from qota's code. Points: random over the Rainier tile (voids
included), pixel centres, cell corners, the raster's edges and corners, and small synthetic
rasters (voids, 3 x 3, 2 x 7). Usage: sampling_rules_check.py QOTA DEM SCRATCH_DIR
"""
import math
import os
import subprocess
import sys

import numpy as np
from osgeo import gdal

gdal.UseExceptions()
qota, dem_path, scratch = sys.argv[1], sys.argv[2], sys.argv[3]
os.makedirs(scratch, exist_ok=True)


def keys(t):
    a = np.abs(t)
    return np.where(a <= 1, 1.5 * a**3 - 2.5 * a**2 + 1, np.where(a <= 2, -0.5 * a**3 + 2.5 * a**2 - 4 * a + 2, 0.0))


def reference(path, xs, ys, rule):
    ds = gdal.Open(path)
    band = ds.GetRasterBand(1)
    v = band.ReadAsArray().astype(np.float64)
    nodata = band.GetNoDataValue()
    void = ~np.isfinite(v) | ((v == nodata) if nodata is not None else False)
    v = v * (band.GetScale() or 1.0) + (band.GetOffset() or 0.0)
    h, w = v.shape
    if rule == "cubic" and (w < 4 or h < 4):
        rule = "bilinear"
    if rule == "bilinear" and (w < 2 or h < 2):
        rule = "nearest"
    inv = gdal.InvGeoTransform(ds.GetGeoTransform())
    out = []
    for x, y in zip(xs, ys):
        col, row = gdal.ApplyGeoTransform(inv, x, y)
        if not (0 <= col <= w and 0 <= row <= h):
            out.append(None)
            continue
        if rule == "nearest":
            i, j = min(int(math.floor(col)), w - 1), min(int(math.floor(row)), h - 1)
            out.append(None if void[j, i] else v[j, i])
            continue
        cx, cy = col - 0.5, row - 0.5
        i, j = math.floor(cx), math.floor(cy)
        dx, dy = cx - i, cy - j
        span = range(0, 2) if rule == "bilinear" else range(-1, 3)
        total = weights = 0.0
        missing = False
        for b in span:
            for a in span:
                ii, jj = min(max(i + a, 0), w - 1), min(max(j + b, 0), h - 1)
                if rule == "bilinear":
                    wt = (dx if a else 1 - dx) * (dy if b else 1 - dy)
                else:
                    wt = float(keys(a - dx) * keys(b - dy))
                if void[jj, ii]:
                    missing = True
                    continue
                total += v[jj, ii] * wt
                weights += wt
        if rule == "bilinear":
            out.append(None if missing else total)
        else:
            out.append(None if weights == 0 else total / weights)
    return out


def qota_sample(path, xs, ys, rule):
    text = "".join(f"{x!r} {y!r}\n" for x, y in zip(xs, ys))
    r = subprocess.run([qota, "sample", path, "-r", rule, "-q", "-p", "17"], input=text, capture_output=True, text=True)
    lines = r.stdout.splitlines()
    assert len(lines) == len(xs), (rule, r.stderr)
    return [None if s == "none" else float(s) for s in lines]


failures = 0


def compare(name, path, xs, ys, rule):
    global failures
    got = qota_sample(path, xs, ys, rule)
    want = reference(path, xs, ys, rule)
    bad = 0
    for k, (g, e) in enumerate(zip(got, want)):
        same = (g is None and e is None) or (
            g is not None and e is not None and abs(g - e) <= 1e-9 * max(1.0, abs(e)))
        if not same:
            bad += 1
            if bad <= 5:
                print(f"{name} {rule}: point {xs[k]!r} {ys[k]!r}: qota {g}, reference {e}")
    failures += bad
    print(f"{name} {rule}: {len(xs) - bad} of {len(xs)} agree ({sum(e is None for e in want)} without a value)")


def grid_points(path, rng, n):
    ds = gdal.Open(path)
    gt, w, h = ds.GetGeoTransform(), ds.RasterXSize, ds.RasterYSize
    cols = list(rng.uniform(0, w, n)) + [c + 0.5 for c in range(min(w, 40))] + [0, w, 0, w, 0.5, w - 0.5, 1, w - 1]
    rows = list(rng.uniform(0, h, n)) + [r + 0.5 for r in range(min(h, 40))] + [0, 0, h, h, h - 0.5, 0.5, h - 1, 1]
    # beside the raster: a hair outside each edge
    cols += [-1e-9 * w, w * (1 + 1e-9), w / 2, w / 2]
    rows += [h / 2, h / 2, -1e-9 * h, h * (1 + 1e-9)]
    xs = [gt[0] + c * gt[1] + r * gt[2] for c, r in zip(cols, rows)]
    ys = [gt[3] + c * gt[4] + r * gt[5] for c, r in zip(cols, rows)]
    return xs, ys


rng = np.random.default_rng(2026)
xs, ys = grid_points(dem_path, rng, 3000)
# voids: points around the tile's void pixels
ds = gdal.Open(dem_path)
a = ds.GetRasterBand(1).ReadAsArray()
vr, vc = np.nonzero(a == ds.GetRasterBand(1).GetNoDataValue())
gt = ds.GetGeoTransform()
for k in rng.choice(len(vr), size=min(500, len(vr)), replace=False):
    c, r = vc[k] + rng.uniform(-1.5, 2.5), vr[k] + rng.uniform(-1.5, 2.5)
    xs.append(gt[0] + c * gt[1])
    ys.append(gt[3] + r * gt[5])
for rule in ("nearest", "bilinear", "cubic"):
    compare("rainier", dem_path, xs, ys, rule)

# nearest against gdallocationinfo itself, on the points it calls on the file (it calls the right
# and bottom edges off; qota takes the last pixel there, checked above)
w, h = ds.RasterXSize, ds.RasterYSize
inv = gdal.InvGeoTransform(gt)
inside = [(x, y) for x, y in zip(xs, ys)
          if 0 <= gdal.ApplyGeoTransform(inv, x, y)[0] < w and 0 <= gdal.ApplyGeoTransform(inv, x, y)[1] < h]
text = "".join(f"{x!r} {y!r}\n" for x, y in inside)
gdal_out = subprocess.run(["gdallocationinfo", "-valonly", "-geoloc", dem_path], input=text, capture_output=True,
                          text=True).stdout.split()
got = qota_sample(dem_path, [p[0] for p in inside], [p[1] for p in inside], "nearest")
nodata = ds.GetRasterBand(1).GetNoDataValue()
bad = sum(1 for g, e in zip(got, gdal_out) if (g is None) != (float(e) == nodata) or (g is not None and g != float(e)))
assert len(gdal_out) == len(inside)
print(f"nearest vs gdallocationinfo: {len(inside) - bad} of {len(inside)} agree")
failures += bad

# Small rasters: voids in a float raster with scale and offset; 3 x 3 and 2 x 7 (cubic becomes
# bilinear). (qota refuses rasters under 2 x 2 pixels, where bilinear would become nearest.)
def small(name, values, nodata, scale=1.0, offset=0.0):
    path = os.path.join(scratch, name + ".tif")
    arr = np.array(values, dtype=np.float32)
    out = gdal.GetDriverByName("GTiff").Create(path, arr.shape[1], arr.shape[0], 1, gdal.GDT_Float32)
    out.SetGeoTransform((100.0, 2.0, 0.0, 50.0, 0.0, -2.0))
    b = out.GetRasterBand(1)
    b.WriteArray(arr)
    if nodata is not None:
        b.SetNoDataValue(nodata)
    b.SetScale(scale)
    b.SetOffset(offset)
    out = None
    return path


r = np.random.default_rng(7)
big = r.uniform(0, 100, (12, 9)).round(2)
big[3, 4] = big[7, 1] = big[0, 0] = -9999
big[5, 5] = np.nan
for name, path in (("voids", small("voids", big, -9999, 0.5, 10)),
                   ("3x3", small("3x3", r.uniform(0, 10, (3, 3)), None)),
                   ("2x7", small("2x7", r.uniform(0, 10, (7, 2)), None))):
    sx, sy = grid_points(path, r, 400)
    for rule in ("nearest", "bilinear", "cubic"):
        compare(name, path, sx, sy, rule)

print("failures:", failures)
sys.exit(1 if failures else 0)
