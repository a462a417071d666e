"""qota.sample: the raster streamed under points, by the exact triangles (Terrain.from_raster's
heights, bit for bit) and by GDAL's rules, against GDAL's own reading of the pixels and a numpy
computation of GDAL's bilinear and cubic kernels written here."""
import numpy as np
import pytest

import qota
from test_terrain import RAINIER

gdal = pytest.importorskip("osgeo.gdal")
gdal.UseExceptions()


def pixels():
    ds = gdal.Open(str(RAINIER))
    band = ds.GetRasterBand(1)
    v = band.ReadAsArray().astype(np.float64)
    v[v == band.GetNoDataValue()] = np.nan
    return v, ds.GetGeoTransform()


def keys(t):
    a = np.abs(t)
    return np.where(a <= 1, 1.5 * a**3 - 2.5 * a**2 + 1, np.where(a <= 2, -0.5 * a**3 + 2.5 * a**2 - 4 * a + 2, 0.0))


def kernel(v, col, row, rule):
    """GDAL's bilinear or cubic at fractional pixel (col, row): centres at +0.5, edge indices
    clamped; bilinear needs all four, cubic renormalises over the valid ones."""
    h, w = v.shape
    cx, cy = col - 0.5, row - 0.5
    i, j = np.floor(cx).astype(int), np.floor(cy).astype(int)
    dx, dy = cx - i, cy - j
    offsets = (0, 1) if rule == "bilinear" else (-1, 0, 1, 2)
    total, weights = np.zeros(col.shape), np.zeros(col.shape)
    for b in offsets:
        for a in offsets:
            z = v[np.clip(j + b, 0, h - 1), np.clip(i + a, 0, w - 1)]
            if rule == "bilinear":
                wt = np.where(a, dx, 1 - dx) * np.where(b, dy, 1 - dy)
                total += z * wt  # NaN spreads: a void among the four leaves none
            else:
                wt = keys(a - dx) * keys(b - dy)
                ok = ~np.isnan(z)
                total += np.where(ok, z, 0) * wt * ok
                weights += wt * ok
    return total if rule == "bilinear" else np.where(weights != 0, total / np.where(weights != 0, weights, 1), np.nan)


def random_points(n, seed):
    rng = np.random.default_rng(seed)
    v, gt = pixels()
    h, w = v.shape
    col, row = rng.uniform(0, w, n), rng.uniform(0, h, n)
    return gt[0] + col * gt[1], gt[3] + row * gt[5], col, row, v


def test_triangle_is_the_terrains_heights():
    x, y, _, _, _ = random_points(5000, 1)
    x = np.append(x, [-130.0, np.nan])
    y = np.append(y, [46.5, 46.5])
    want = qota.Terrain.from_raster(RAINIER).heights(x, y)
    got = qota.sample(RAINIER, x, y)
    np.testing.assert_array_equal(got, want)
    assert np.isnan(got[-2:]).all()
    # any shape, broadcast
    grid = qota.sample(RAINIER, x[:20].reshape(4, 5), y[:20].reshape(4, 5))
    assert grid.shape == (4, 5)
    np.testing.assert_array_equal(grid.ravel(), want[:20])


def test_gdal_rules_against_the_pixels():
    x, y, col, row, v = random_points(5000, 2)
    near = qota.sample(RAINIER, x, y, resampling="nearest")
    np.testing.assert_array_equal(near, v[row.astype(int), col.astype(int)])
    for rule in ("bilinear", "cubic"):
        got = qota.sample(RAINIER, x, y, resampling=rule)
        want = kernel(v, col, row, rule)
        np.testing.assert_array_equal(np.isnan(got), np.isnan(want))
        ok = ~np.isnan(want)
        np.testing.assert_allclose(got[ok], want[ok], rtol=1e-9)  # (renormalised sums near voids: rounding)


def test_points_in_another_crs():
    # The summit in UTM zone 10 N, against the same point in longitude/latitude.
    lon, lat = np.array([-121.7603, -121.5]), np.array([46.8529, 46.7])
    osr = pytest.importorskip("osgeo.osr")
    wgs, utm = osr.SpatialReference(), osr.SpatialReference()
    wgs.ImportFromEPSG(4326), utm.ImportFromEPSG(32610)
    wgs.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
    utm.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
    ct = osr.CoordinateTransformation(wgs, utm)
    e, n = np.array([ct.TransformPoint(a, b)[:2] for a, b in zip(lon, lat)]).T
    got = qota.sample(RAINIER, e, n, srs="EPSG:32610", resampling="nearest")
    np.testing.assert_allclose(got, qota.sample(RAINIER, lon, lat, resampling="nearest"))


def test_refusals():
    with pytest.raises(qota.Error, match="resampling must be one of"):
        qota.sample(RAINIER, [0], [0], resampling="lanczos")
    with pytest.raises(qota.Error, match="srs"):
        qota.sample(RAINIER, [0], [0], srs="EPSG:999999")
    with pytest.raises(qota.Error, match="do not broadcast"):
        qota.sample(RAINIER, [0, 1], [0, 1, 2])


def test_a_geodataframe_gets_a_height_column():
    gpd = pytest.importorskip("geopandas")
    shapely = pytest.importorskip("shapely.geometry")
    x, y, col, row, v = random_points(200, 3)
    frame = gpd.GeoDataFrame({"name": [f"p{i}" for i in range(200)]},
                             geometry=[shapely.Point(a, b) for a, b in zip(x, y)], crs="EPSG:4326")
    got = qota.sample(RAINIER, frame, resampling="nearest")
    assert list(got.columns) == ["name", "geometry", "height"] and "height" not in frame.columns
    np.testing.assert_array_equal(got["height"].to_numpy(), v[row.astype(int), col.astype(int)])
    # In another CRS: the frame's own is used.
    utm = frame.to_crs("EPSG:32610")
    np.testing.assert_allclose(qota.sample(RAINIER, utm, resampling="nearest")["height"], got["height"])
    # An empty geometry and a point off the raster have none; non-points are refused.
    frame.loc[0, "geometry"] = shapely.Point()
    frame.loc[1, "geometry"] = shapely.Point(-130, 40)
    h = qota.sample(RAINIER, frame, field="elev")["elev"].to_numpy()
    assert np.isnan(h[:2]).all() and not np.isnan(h[2:]).all()
    with pytest.raises(qota.Error, match="already has a column"):
        qota.sample(RAINIER, got)
    lines = gpd.GeoDataFrame(geometry=[shapely.LineString([(0, 0), (1, 1)])])
    with pytest.raises(qota.Error, match="must be points"):
        qota.sample(RAINIER, lines)


def test_tool_errors_speak_python(tmp_path):
    with pytest.raises(qota.Error) as e:
        qota.shadow(RAINIER, time="2024-06-21T12:00")
    assert "give tz" in str(e.value) and "--tz" not in str(e.value) and not str(e.value).startswith("qota ")
    with pytest.raises(qota.Error, match="z_factor must be a positive number"):
        qota.shadow(RAINIER, azimuth=100, altitude=20, z_factor=-1)
    with pytest.raises(qota.Error) as e:
        qota.viewshed(RAINIER, observer=(-130, 40))
    assert str(e.value).startswith("the observer at -130, 40 is not on")


def test_shadow_png_preview(tmp_path):
    png = tmp_path / "preview.png"
    mask = qota.shadow(RAINIER, azimuth=135, altitude=20, png=png)
    preview = gdal.Open(str(png))
    # the picture, and the legend strip below it
    assert preview.RasterXSize == max(mask.shape[1], 360) and preview.RasterYSize > mask.shape[0] + 30
    assert preview.RasterCount == 4
