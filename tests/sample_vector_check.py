#!/usr/bin/python3
"""qota sample -i POINTS -o OUT on vector layers, checked through OGR's own reading and writing.

Points at pixel centres of the Rainier tile (where every rule gives the raster's own value, read
here by GDAL), beside voids and off the raster, with fields of several types, are written by OGR
as GeoJSON (lon/lat), GeoPackage (UTM 10N), Shapefile, FlatGeobuf and CSV (lon/lat columns,
quoted; and a WKT column); qota samples each and writes GeoPackage, GeoJSON, Shapefile, FlatGeobuf
and CSV; OGR reads the result back: every feature, field and geometry as it was, the height
field the raster's value (null on a void or off the raster), and the exit code 1 when a point was
off the raster. Usage: sample_vector_check.py QOTA DEM SCRATCH_DIR
"""
import os
import shutil
import subprocess
import sys

import numpy as np
from osgeo import gdal, ogr, osr

gdal.UseExceptions()
qota, dem_path, scratch = sys.argv[1], sys.argv[2], sys.argv[3]
shutil.rmtree(scratch, ignore_errors=True)
os.makedirs(scratch)

ds = gdal.Open(dem_path)
band = ds.GetRasterBand(1)
values = band.ReadAsArray()
nodata = band.GetNoDataValue()
gt = ds.GetGeoTransform()
rng = np.random.default_rng(5)

# Pixel centres: some valid, some voids; one point off the raster.
rows, cols = np.nonzero(values != nodata)
pick = rng.choice(len(rows), 300, replace=False)
vr, vc = np.nonzero(values == nodata)
vpick = rng.choice(len(vr), 20, replace=False)
pr = np.concatenate([rows[pick], vr[vpick]])
pc = np.concatenate([cols[pick], vc[vpick]])
lon = list(gt[0] + (pc + 0.5) * gt[1])
lat = list(gt[3] + (pr + 0.5) * gt[5])
expected = [float(values[r, c]) if values[r, c] != nodata else None for r, c in zip(pr, pc)]
lon.append(-130.0)
lat.append(40.0)
expected.append(None)
n = len(lon)

wgs = osr.SpatialReference()
wgs.ImportFromEPSG(4326)
wgs.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
utm = osr.SpatialReference()
utm.ImportFromEPSG(32610)
utm.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
to_utm = osr.CoordinateTransformation(wgs, utm)


def write_layer(path, driver, srs, coords, options=()):
    out = ogr.GetDriverByName(driver).CreateDataSource(path)
    layer = out.CreateLayer("points", srs, ogr.wkbPoint, options=list(options))
    layer.CreateField(ogr.FieldDefn("name", ogr.OFTString))
    layer.CreateField(ogr.FieldDefn("rank", ogr.OFTInteger))
    layer.CreateField(ogr.FieldDefn("weight", ogr.OFTReal))
    for i, (x, y) in enumerate(coords):
        f = ogr.Feature(layer.GetLayerDefn())
        f.SetField("name", f"p{i}, \"q\"")
        f.SetField("rank", i)
        f.SetField("weight", i * 0.25)
        f.SetGeometry(ogr.CreateGeometryFromWkt(f"POINT ({x!r} {y!r})"))
        layer.CreateFeature(f)
    out = None


inputs = {}
lonlat = list(zip(lon, lat))
inputs["geojson"] = os.path.join(scratch, "in.geojson")
write_layer(inputs["geojson"], "GeoJSON", wgs, lonlat)
inputs["gpkg_utm"] = os.path.join(scratch, "in_utm.gpkg")
write_layer(inputs["gpkg_utm"], "GPKG", utm, [to_utm.TransformPoint(x, y)[:2] for x, y in lonlat])
inputs["shp"] = os.path.join(scratch, "in.shp")
write_layer(inputs["shp"], "ESRI Shapefile", wgs, lonlat)
inputs["fgb"] = os.path.join(scratch, "in.fgb")
write_layer(inputs["fgb"], "FlatGeobuf", wgs, lonlat)
# CSV with quoted lon/lat columns (no CRS: the raster's), and one with a WKT column.
inputs["csv"] = os.path.join(scratch, "in.csv")
with open(inputs["csv"], "w") as f:
    f.write('name,lon,lat,rank\n')
    for i, (x, y) in enumerate(lonlat):
        f.write(f'"p{i}","{x!r}","{y!r}",{i}\n')
inputs["csv_wkt"] = os.path.join(scratch, "in_wkt.csv")
with open(inputs["csv_wkt"], "w") as f:
    f.write('WKT,rank\n')
    for i, (x, y) in enumerate(lonlat):
        f.write(f'"POINT ({x!r} {y!r})",{i}\n')

failures = 0


def check(name, source, output, extra=()):
    global failures
    r = subprocess.run([qota, "sample", dem_path, "-i", source, "-o", output, *extra], capture_output=True, text=True)
    problems = []
    if r.returncode != 1:  # (one point is off the raster)
        problems.append(f"exit {r.returncode}: {r.stderr}")
    if "feature" not in r.stderr or "off the raster" not in r.stderr:
        problems.append(f"no message names the point off the raster: {r.stderr!r}")
    written = ogr.Open(output)
    if written is None:
        problems.append("no output")
    else:
        layer = written.GetLayer(0)
        features = sorted(layer, key=lambda f: int(f.GetField("rank")))
        if len(features) != n:
            problems.append(f"{len(features)} features, not {n}")
        for i, f in enumerate(features):
            h = None if not f.IsFieldSetAndNotNull("height") else f.GetField("height")
            h = None if h in (None, "") else float(h)  # (a CSV's fields read back as text)
            want = expected[i]
            if (h is None) != (want is None) or (h is not None and abs(h - want) > 1e-6):
                problems.append(f"point {i}: height {h}, raster {want}")
            if int(f.GetField("rank")) != i:
                problems.append(f"point {i}: rank {f.GetField('rank')}")
            if layer.GetLayerDefn().GetFieldIndex("name") >= 0 and not str(f.GetField("name")).startswith(f"p{i}"):
                problems.append(f"point {i}: name {f.GetField('name')!r}")
        if problems[-1:] and len(problems) > 5:
            problems = problems[:5]
    failures += len(problems)
    print(f"{name}: {'ok' if not problems else problems}")


for kind, source in inputs.items():
    # (UTM coordinates come back to lon/lat a hair off the centres: beside a void that hair can
    # fall in a triangle of the void; the pixel containing the point is still the centre's)
    extra = ("-r", "nearest") if kind == "gpkg_utm" else ()
    for ext in ("gpkg", "geojson", "shp", "fgb", "csv"):
        check(f"{kind} -> {ext}", source, os.path.join(scratch, f"{kind}_out.{ext}"), extra)

# GeoJSON in, its fields and geometry out as they were; --field names the heights.
out = os.path.join(scratch, "named.geojson")
r = subprocess.run([qota, "sample", dem_path, "-i", inputs["geojson"], "-o", out, "--field", "elev", "-q"],
                   capture_output=True, text=True)
named = ogr.Open(out)
f = named.GetLayer(0).GetNextFeature()
ok = (f.GetField("elev") == expected[0] and f.GetField("name") == 'p0, "q"' and f.GetField("weight") == 0.0
      and abs(f.GetGeometryRef().GetX() - lon[0]) < 1e-12)
print("named field, fields and geometry kept:", "ok" if ok else "wrong")
failures += not ok

# Refusals: a field already named height, a vector output of text lines, no -o for a layer;
# nothing written.
def refused(args, needle, name):
    global failures
    r = subprocess.run([qota, "sample", dem_path, *args], capture_output=True, text=True, input="-121.5 46.5\n")
    ok = r.returncode == 2 and needle in r.stderr
    print(f"refused {name}:", "ok" if ok else (r.returncode, r.stderr))
    failures += not ok


refused(["-i", out, "-o", os.path.join(scratch, "twice.gpkg"), "--field", "elev"], "already has a field", "a field twice")
refused(["-o", os.path.join(scratch, "text.gpkg")], "read as lines of text", "text to a layer")
refused(["-i", inputs["gpkg_utm"]], "give -o OUT", "no output")
for name in ("twice.gpkg", "text.gpkg"):
    if os.path.exists(os.path.join(scratch, name)):
        print("written though refused:", name)
        failures += 1

# Quoted numbers on text lines (a spreadsheet's CSV).
r = subprocess.run([qota, "sample", dem_path, "-r", "nearest"], capture_output=True, text=True,
                   input=f'"{lon[0]!r}","{lat[0]!r}",x\n')
ok = r.stdout == f"{expected[0]:g},x\n"
print("quoted fields on text lines:", "ok" if ok else (r.stdout, r.stderr))
failures += not ok

print("failures:", failures)
sys.exit(1 if failures else 0)
