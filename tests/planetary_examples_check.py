#!/usr/bin/python3
"""The README's Mars and Moon commands on the bundled stand-ins (data/mars_etopo20.vrt and
data/moon_etopo20.vrt: the global 20' relief on each body's IAU 2015 sphere), checked against
spherical geometry computed here from published or given sub-solar points, not from qota. No
facet of the triangulated terrain within 80 degrees of the equator is steeper than S (a bound
computed here from the heights and the body's radius), so between 70 S and 70 N every pixel whose
Sun stands more than S + 1 degrees above its horizon must be lit (no facet faces away, and a ray
that climbs faster than any slope meets nothing before it leaves 80 degrees), and every one whose
Sun is more than S + 1 degrees below it must be in shadow. The outputs must name the body and
record the light they were given.
Usage: planetary_examples_check.py QOTA DATA_DIR SCRATCH
"""
import math
import os
import shutil
import subprocess
import sys

import numpy as np
from osgeo import gdal

gdal.UseExceptions()
qota, data, scratch = sys.argv[1], sys.argv[2], sys.argv[3]
shutil.rmtree(scratch, ignore_errors=True)
os.makedirs(scratch)
RADIUS = {"mars": 3396190.0, "moon": 1737400.0}  # the IAU 2015 spheres (IAU_2015:49900, 30100)


def unit_at(lon, lat):
    lon, lat = math.radians(lon), math.radians(lat)
    return np.array([math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat)])


# Mars24's worked examples (Allison and McEwen 2000; the Mars24 algorithm page):
# A: 2000-01-06 00:00 UTC, the Sun over 174.72703 W, 25.22838 S;
# B: 2004-01-03 13:46:31 UTC, sub-solar longitude 4.70575 W, declination -13.42105.
EXAMPLE_A = unit_at(-174.72703, -25.22838)
EXAMPLE_B = unit_at(-4.70575, -13.42105)
v = np.array([0.999, 0.02, 0.026])
BODY_VECTOR = v / np.linalg.norm(v)
# east, north, up at the raster's centre (0, 0): east is +y, north +z, up +x in the body frame.
e, n, u = 0.3, -0.5, 0.8
ENU_AT_CENTRE = np.array([u, e, n]) / math.sqrt(e * e + n * n + u * u)

cases = [
    ("mars", ["--time", "2004-01-03T13:46:31Z"], EXAMPLE_B, "on the Mars ellipsoid"),
    ("mars", ["--time", "2000-01-06T00:00:00Z"], EXAMPLE_A, "on the Mars ellipsoid"),
    ("mars", ["--subsolar", "-174.72703,-25.22838"], EXAMPLE_A, "on the Mars ellipsoid"),
    ("moon", ["--sun-vector-body", "0.999,0.02,0.026"], BODY_VECTOR, "on the Moon ellipsoid"),
    ("moon", ["--sun-vector", "0.3,-0.5,0.8"], ENU_AT_CENTRE, "on the Moon ellipsoid"),
]


def steepest_facet(path, radius):
    """A bound on the slope of every grid triangle within 80 degrees of the equator, in degrees:
    a triangle's two legs run along a row and a column, so its gradient is at most the hypot of
    the steepest row and column differences over their lengths on the sphere."""
    ds = gdal.Open(path)
    h = ds.GetRasterBand(1).ReadAsArray().astype(float)
    gt = ds.GetGeoTransform()
    lat = np.radians(gt[3] + (np.arange(h.shape[0]) + 0.5) * gt[5])
    rows = np.abs(lat) <= math.radians(80)
    step = math.radians(abs(gt[1])) * radius
    band = h[rows]
    along = np.abs(np.diff(np.concatenate([band, band[:, :1]], 1), axis=1)) / (step * np.cos(lat[rows]))[:, None]
    across = np.abs(np.diff(h[np.flatnonzero(rows).min() - 1:np.flatnonzero(rows).max() + 2], axis=0)) / step
    return math.degrees(math.atan(math.hypot(along.max(), across.max())))


failures = 0
for i, (body, light, sun, says) in enumerate(cases):
    out = os.path.join(scratch, f"{body}{i}.tif")
    dem = os.path.join(data, f"{body}_etopo20.vrt")
    margin = math.sin(math.radians(steepest_facet(dem, RADIUS[body]) + 1))
    r = subprocess.run([qota, "shadow", dem, *light, "-o", out],
                       capture_output=True, text=True)
    if r.returncode != 0 or says not in r.stdout:
        print(f"FAILED {body} {' '.join(light)}: exit {r.returncode}\n{r.stdout}{r.stderr}")
        failures += 1
        continue
    ds = gdal.Open(out)
    mask = ds.GetRasterBand(1).ReadAsArray()
    gt = ds.GetGeoTransform()
    meta = ds.GetMetadata()
    ds = None
    rows, cols = mask.shape
    lon = np.radians(gt[0] + (np.arange(cols) + 0.5) * gt[1])[None, :]
    lat = np.radians(gt[3] + (np.arange(rows) + 0.5) * gt[5])[:, None]
    sin_elevation = (np.cos(lat) * np.cos(lon) * sun[0] + np.cos(lat) * np.sin(lon) * sun[1]
                     + np.sin(lat) * sun[2])
    within = np.abs(lat) <= math.radians(70)
    day = (sin_elevation > margin) & within
    night = (sin_elevation < -margin) & within
    wrong_day = int((day & (mask != 255)).sum())
    wrong_night = int((night & (mask != 0)).sum())
    recorded = " ".join(light[1:]).split(",")[0] in meta.get("QOTA_COMMAND", "")
    print(f"{body} {' '.join(light)} (margin {math.degrees(math.asin(margin)):.1f} deg): {int(day.sum())} day pixels, {wrong_day} not lit; "
          f"{int(night.sum())} night pixels, {wrong_night} lit; light recorded: {recorded}")
    failures += wrong_day + wrong_night + (not recorded) + (day.sum() < 20000) + (night.sum() < 20000)
print(f"failures: {failures}")
sys.exit(1 if failures else 0)
