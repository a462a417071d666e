#!/usr/bin/python3
"""--fill-voids against GDAL's own fill-nodata: a Float32 crop of the Rainier tile (its SRTM voids
near the summit) is filled by GDAL (gdal.FillNodata on the file's band, its -32768 nodata, 100
pixels: what gdal_fillnodata.py does), and qota sample --fill-voids at every void pixel's centre
must give the filled value; qota shadow and viewshed --fill-voids write values where the voids
were and record it; what cannot be done is refused. Usage: fill_voids_check.py QOTA DEM SCRATCH
"""
import os
import shutil
import subprocess
import sys

import numpy as np
from osgeo import gdal

gdal.UseExceptions()
qota, dem_path, scratch = sys.argv[1], sys.argv[2], sys.argv[3]
shutil.rmtree(scratch, ignore_errors=True)
os.makedirs(scratch)
crop = os.path.join(scratch, "crop.tif")
gdal.Translate(crop, dem_path, srcWin=[150, 100, 250, 200], outputType=gdal.GDT_Float32)
filled = os.path.join(scratch, "filled.tif")
gdal.Translate(filled, crop)
ds = gdal.Open(filled, gdal.GA_Update)
band = ds.GetRasterBand(1)
before = band.ReadAsArray()
nodata = band.GetNoDataValue()
gdal.FillNodata(band, None, 100, 0)
after = band.ReadAsArray()
gt = ds.GetGeoTransform()
ds = None
rows, cols = np.nonzero(before == nodata)
failures = 0
print(f"{len(rows)} void pixels in the crop")
if len(rows) < 50:
    print("too few voids to test")
    failures += 1
text = "".join(f"{gt[0] + (c + 0.5) * gt[1]!r} {gt[3] + (r + 0.5) * gt[5]!r}\n" for r, c in zip(rows, cols))
r = subprocess.run([qota, "sample", crop, "--fill-voids", "-p", "17"], input=text, capture_output=True, text=True)
got = r.stdout.split()
bad = sum(1 for g, (rr, cc) in zip(got, zip(rows, cols))
          if g == "none" or abs(float(g) - after[rr, cc]) > 1e-3 * max(1.0, abs(after[rr, cc])))
print(f"sample --fill-voids: {len(got) - bad} of {len(rows)} void centres have GDAL's filled value")
failures += bad + (len(got) != len(rows))
r = subprocess.run([qota, "sample", crop], input=text, capture_output=True, text=True)
print("without it:", "all none" if set(r.stdout.split()) == {"none"} else "not all none")
failures += set(r.stdout.split()) != {"none"}

# info --tree: the terrain built on the filled raster
r = subprocess.run([qota, "info", crop, "--tree", "--fill-voids", "--json"], capture_output=True, text=True)
import json  # noqa: E402
info = json.loads(r.stdout) if r.returncode == 0 else {}
want = int(((before == nodata) & (after != nodata)).sum())
ok = info.get("voids_filled") == want and info.get("triangles") == 2 * 249 * 199
print("info --tree --fill-voids:", "ok" if ok else (info.get("voids_filled"), want, info.get("triangles"), r.stderr))
failures += not ok

# shadow and viewshed: values where the voids were, recorded
for tool, args in (("shadow", ["-az", "135", "-alt", "20"]),
                   ("viewshed", ["--observer", "-121.7326,46.8356", "--oz", "10"])):
    out = os.path.join(scratch, f"{tool}.tif")
    r = subprocess.run([qota, tool, crop, *args, "--fill-voids", "-o", out, "-q"], capture_output=True, text=True)
    o = gdal.Open(out)
    values = o.GetRasterBand(1).ReadAsArray()
    ok = r.returncode == 0 and (values[before == nodata] != 128).all() and "fill-nodata" in o.GetMetadataItem(
        "QOTA_FILL_VOIDS")
    print(f"{tool} --fill-voids:", "ok" if ok else (r.returncode, r.stderr))
    failures += not ok
    o = None

# refused: by tiles, with a GDAL rule
for args, needle in ((["shadow", crop, "-az", "1", "-alt", "9", "--fill-voids", "--tile-size", "64", "-o",
                       os.path.join(scratch, "t.tif")], "fill it first"),
                     (["sample", crop, "--fill-voids", "-r", "nearest"], "gdal_fillnodata")):
    r = subprocess.run([qota, *args], input="1 2\n", capture_output=True, text=True)
    ok = r.returncode == 2 and needle in r.stderr
    print("refused:", args[0], "ok" if ok else (r.returncode, r.stderr))
    failures += not ok
print("failures:", failures)
sys.exit(1 if failures else 0)
