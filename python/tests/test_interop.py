"""rasterio datasets and xarray DataArrays (rioxarray) as sources: every way of handing qota the
same raster gives the terrain of a numpy brute force over its triangles (test_terrain's, and
test_mappings' ellipsoid for lon/lat), and the same answers as the file; qota.shadow of a
DataArray is the file's mask cell for cell, on the DataArray's own grid and CRS. Rasters are
written here with rasterio, not with qota."""
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import qota
from test_mappings import WGS84_A, WGS84_F, answers, assert_matches, crossings, ellipsoid_mesh, normal_lines
from test_terrain import brute_force

rasterio = pytest.importorskip("rasterio")
xr = pytest.importorskip("xarray")
rioxarray = pytest.importorskip("rioxarray")
from rasterio.io import MemoryFile  # noqa: E402
from rasterio.transform import Affine  # noqa: E402
from rasterio.windows import Window  # noqa: E402

DATA = Path(os.environ.get("QOTA_DATA_DIR", Path(__file__).resolve().parents[2] / "data"))
RAINIER = DATA / "mt_rainier_90m.tif"
NODATA = -9999.0


def utm_raster(rng, rows=30, cols=40):
    """Float32 heights on a 30 m UTM grid, with nodata pixels."""
    heights = rng.uniform(100, 900, (rows, cols)).astype(np.float32)
    heights[4, 7] = heights[20, 31] = heights[12, 0] = NODATA
    return heights, Affine(30.0, 0.0, 500000.0, 0.0, -30.0, 5200000.0), "EPSG:32610"


def write_tif(path, heights, transform, crs, unit=None):
    profile = dict(driver="GTiff", width=heights.shape[1], height=heights.shape[0], count=1, dtype=heights.dtype.name,
                   crs=crs, transform=transform, nodata=NODATA)
    with rasterio.open(path, "w", **profile) as dst:
        dst.write(heights, 1)
        if unit:
            dst.units = (unit,)
    return path


def grid_mesh(heights, transform):
    """The raster's terrain for the brute force: pixel centres, two triangles a cell split along
    the top-left to bottom-right diagonal, none touching a nodata centre."""
    rows, cols = heights.shape
    r, c = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    x, y = transform * (c.ravel() + 0.5, r.ravel() + 0.5)
    z = heights.ravel().astype(float)
    valid = z != NODATA
    tris = []
    for i in range(rows - 1):
        for j in range(cols - 1):
            tl, tr, bl, br = i * cols + j, i * cols + j + 1, (i + 1) * cols + j, (i + 1) * cols + j + 1
            tris += [t for t in ([tl, bl, br], [tl, br, tr]) if valid[t].all()]
    return np.column_stack([x, y, z]), np.array(tris)


def every_source(path, stack):
    """The same raster as a path, a rasterio dataset on the file, a rasterio dataset in memory,
    and DataArrays: rioxarray's (band, y, x) raw and masked, one band (y, x), and one built from
    bare coordinates with a CRS and nodata written by rioxarray."""
    ds = stack(rasterio.open(path))
    memfile = stack(MemoryFile(Path(path).read_bytes()))
    in_memory = stack(memfile.open())
    raw = rioxarray.open_rasterio(path)
    masked = rioxarray.open_rasterio(path, masked=True)
    values = raw.isel(band=0).values
    built = xr.DataArray(values, dims=("y", "x"), coords={"y": raw.y.values, "x": raw.x.values})
    built = built.rio.write_crs(raw.rio.crs).rio.write_nodata(NODATA)
    return {"path": path, "dataset": ds, "memory dataset": in_memory, "DataArray": raw, "masked": masked,
            "2-D": raw.squeeze("band"), "built": built}


@pytest.fixture
def stack():
    """Closes what a test opened."""
    opened = []
    yield lambda obj: opened.append(obj) or obj
    for obj in reversed(opened):
        obj.close()


def test_every_source_is_the_rasters_terrain(tmp_path, stack):
    rng = np.random.default_rng(30)
    heights, transform, crs = utm_raster(rng)
    path = write_tif(tmp_path / "utm.tif", heights, transform, crs)
    v, t = grid_mesh(heights, transform)
    x = rng.uniform(500000 + 15, 500000 + 30 * 39 + 15, 3000)
    y = rng.uniform(5200000 - 30 * 29 - 15, 5200000 - 15, 3000)
    want, near = brute_force(v, t, x, y)
    assert np.count_nonzero(np.isnan(want)) > 10  # the holes are asked about
    reference = qota.Terrain.from_raster(path).heights(x, y)
    for name, source in every_source(path, stack).items():
        terrain = qota.Terrain.from_raster(source)
        got = terrain.heights(x, y)
        clear = ~near
        np.testing.assert_array_equal(np.isnan(got[clear]), np.isnan(want[clear]), err_msg=name)
        ok = clear & ~np.isnan(want)
        np.testing.assert_allclose(got[ok], want[ok], rtol=0, atol=1e-6, err_msg=name)
        np.testing.assert_array_equal(got, reference, err_msg=name)
        assert terrain.mapping == "cartesian" and "UTM zone 10N" in terrain.crs, name
        if name.startswith("DataArray") or name in ("2-D", "built", "masked"):
            np.testing.assert_array_equal(qota.Terrain.from_xarray(source).heights(x, y), reference, err_msg=name)


def test_a_sliced_dataarray_is_its_own_raster(tmp_path):
    # A window of the DataArray: its transform comes from its own coordinates, not from the
    # GeoTransform the file's spatial_ref still carries.
    rng = np.random.default_rng(31)
    heights, transform, crs = utm_raster(rng)
    path = write_tif(tmp_path / "utm.tif", heights, transform, crs)
    window = rioxarray.open_rasterio(path).isel(y=slice(5, 25), x=slice(10, 32))
    v, t = grid_mesh(heights[5:25, 10:32], transform * Affine.translation(10, 5))
    x = rng.uniform(500000 + 30 * 10 + 15, 500000 + 30 * 31 + 15, 2000)
    y = rng.uniform(5200000 - 30 * 24 - 15, 5200000 - 30 * 5 - 15, 2000)
    want, near = brute_force(v, t, x, y)
    got = qota.Terrain.from_raster(window).heights(x, y)
    np.testing.assert_array_equal(np.isnan(got[~near]), np.isnan(want[~near]))
    ok = ~near & ~np.isnan(want)
    np.testing.assert_allclose(got[ok], want[ok], rtol=0, atol=1e-6)


def test_lon_lat_sources_in_the_geodetic_mapping(tmp_path, stack):
    # A lon/lat raster in feet: the path, a dataset and a DataArray (whose `units` attribute
    # carries the feet) give the same heights along the WGS84 normal, in feet.
    rng = np.random.default_rng(32)
    heights = rng.uniform(700, 14000, (12, 15)).astype(np.float32)
    heights[5, 6] = NODATA
    transform = Affine(0.01, 0.0, -122.0, 0.0, -0.01, 47.0)
    path = write_tif(tmp_path / "feet.tif", heights, transform, "EPSG:4326", unit="ft")
    v, t = ellipsoid_mesh(np.where(heights == NODATA, np.nan, heights), transform.to_gdal(), WGS84_A, WGS84_F,
                          metres=0.3048)
    n = 1500
    lon, lat = rng.uniform(-121.995, -121.855, n), rng.uniform(46.885, 46.995, n)
    o, d = normal_lines(lon, lat, WGS84_A, WGS84_F)
    hits, near = crossings(o, d, v, t)
    want = answers(hits) / 0.3048
    sources = every_source(path, stack)
    for name in ("path", "dataset", "memory dataset", "DataArray", "masked"):
        terrain = qota.Terrain.from_raster(sources[name], mapping="geodetic", height_ref="ellipsoid")
        assert terrain.mapping == "geodetic"
        assert_matches(terrain.heights(lon, lat), want, near)
    spherical = qota.Terrain.from_xarray(sources["DataArray"], mapping="spherical", radius=3389500.0)
    np.testing.assert_array_equal(spherical.heights(lon, lat),
                                  qota.Terrain.from_raster(path, mapping="spherical", radius=3389500.0).heights(lon, lat))


def test_scaled_values_are_decoded(tmp_path):
    # A DataArray of raw values with scale_factor/add_offset attributes (open_rasterio without
    # mask_and_scale) is decoded as GDAL decodes the file.
    rng = np.random.default_rng(33)
    raw = rng.integers(0, 2000, (10, 12)).astype(np.int16)
    raw[3, 3] = -9999
    path = tmp_path / "scaled.tif"
    with rasterio.open(path, "w", driver="GTiff", width=12, height=10, count=1, dtype="int16", crs="EPSG:32610",
                       transform=Affine(10, 0, 0, 0, -10, 100), nodata=-9999) as dst:
        dst.write(raw, 1)
        dst.scales, dst.offsets = (0.5,), (100.0,)
    da = rioxarray.open_rasterio(path)
    assert da.attrs["scale_factor"] == 0.5 and da.attrs["add_offset"] == 100.0
    x, y = rng.uniform(5, 115, 500), rng.uniform(5, 95, 500)
    want = qota.Terrain.from_raster(path).heights(x, y)
    assert np.nanmax(want) > 500  # decoded: raw * 0.5 + 100
    np.testing.assert_array_equal(qota.Terrain.from_raster(da).heights(x, y), want)
    with rasterio.open(path) as ds, MemoryFile(path.read_bytes()) as mem, mem.open() as in_memory:
        assert in_memory.scales == (0.5,)
        np.testing.assert_array_equal(qota.Terrain.from_raster(in_memory).heights(x, y), want)
        np.testing.assert_array_equal(qota.Terrain.from_raster(ds).heights(x, y), want)


def test_rainier_from_a_dataset_and_a_dataarray_equals_the_file(stack):
    rng = np.random.default_rng(34)
    x, y = rng.uniform(-122, -121, 100000), rng.uniform(46, 47, 100000)
    want = qota.Terrain.from_raster(RAINIER).heights(x, y)
    ds = stack(rasterio.open(RAINIER))
    np.testing.assert_array_equal(qota.Terrain.from_raster(ds).heights(x, y), want)
    np.testing.assert_array_equal(qota.Terrain.from_raster(rioxarray.open_rasterio(RAINIER)).heights(x, y), want)


def assert_same_grid(mask, dem):
    """The mask is a uint8 DataArray on the DEM's grid: its dimensions, coordinates, transform
    and CRS, 128 declared as nodata."""
    assert mask.dtype == np.uint8 and mask.dims == dem.dims and mask.shape == dem.shape
    for name in dem.dims:
        np.testing.assert_array_equal(mask[name].values, dem[name].values)
    assert mask.rio.crs == dem.rio.crs and mask.rio.crs is not None
    assert mask.rio.transform() == dem.rio.transform()
    assert mask.rio.nodata == 128


def test_shadow_of_a_dataarray_is_the_files_mask(tmp_path, stack):
    want = qota.shadow(RAINIER, azimuth=135, altitude=20)
    assert (want == 0).any() and (want == 255).any() and (want == 128).any()
    da = rioxarray.open_rasterio(RAINIER)
    for dem in (da, da.squeeze("band"), rioxarray.open_rasterio(RAINIER, masked=True)):
        got = qota.shadow(dem, azimuth=135, altitude=20)
        assert isinstance(got, xr.DataArray)
        assert_same_grid(got, dem)
        np.testing.assert_array_equal(got.values.reshape(want.shape), want)
    # Rasterio datasets: on the file, and in memory.
    for ds in (stack(rasterio.open(RAINIER)), stack(stack(MemoryFile(RAINIER.read_bytes())).open())):
        got = qota.shadow(ds, azimuth=135, altitude=20)
        assert_same_grid(got, da)
        np.testing.assert_array_equal(got.values[0], want)
    # The Sun at an instant, the GeoTIFF kept: the same pixels in the file, with the CRS.
    got = qota.shadow(da.squeeze("band"), time="2024-06-21T18:30", tz="America/Los_Angeles", output=tmp_path / "s.tif")
    kept = rioxarray.open_rasterio(tmp_path / "s.tif")
    np.testing.assert_array_equal(kept.values[0], got.values)
    assert kept.rio.crs == da.rio.crs
    np.testing.assert_array_equal(got.values, qota.shadow(RAINIER, time="2024-06-21T18:30", tz="America/Los_Angeles"))


def test_viewshed_of_a_dataarray_is_the_files(stack):
    # Within 12 km, so the in-memory copies (written to a temporary GeoTIFF) stay quick.
    kwargs = dict(observer=(-121.78, 46.83), observer_height=10, max_distance=12000)
    want = qota.viewshed(RAINIER, **kwargs)
    assert (want == 0).any() and (want == 255).any() and (want == 64).any()
    da = rioxarray.open_rasterio(RAINIER)
    for dem in (da, da.squeeze("band")):
        got = qota.viewshed(dem, **kwargs)
        assert isinstance(got, xr.DataArray) and got.name == "viewshed"
        assert_same_grid(got, dem)
        np.testing.assert_array_equal(got.values.reshape(want.shape), want)
    got = qota.viewshed(stack(stack(MemoryFile(RAINIER.read_bytes())).open()), **kwargs)
    np.testing.assert_array_equal(got.values[0], want)


def test_shadow_of_a_dataarray_keeps_its_vertical_unit(tmp_path):
    # A DEM in feet: the DataArray's `units` reaches the shadow as the file's unit type does.
    with rasterio.open(RAINIER) as ds:
        window = Window(300, 300, 400, 300)
        heights = ds.read(1, window=window).astype(np.float32)
        transform = ds.window_transform(window)
    heights[heights == -32768] = NODATA
    path = write_tif(tmp_path / "feet.tif", heights, transform, "EPSG:4326", unit="ft")
    want = qota.shadow(path, azimuth=250, altitude=12)
    da = rioxarray.open_rasterio(path)
    assert da.attrs["units"] == "ft"
    got = qota.shadow(da, azimuth=250, altitude=12)
    np.testing.assert_array_equal(got.values[0], want)
    metres = write_tif(tmp_path / "metres.tif", heights, transform, "EPSG:4326")
    assert (qota.shadow(metres, azimuth=250, altitude=12) != want).any()  # the unit mattered


def test_interop_errors(tmp_path):
    da = rioxarray.open_rasterio(RAINIER)
    with pytest.raises(qota.Error, match="Dataset"):
        qota.Terrain.from_raster(da.to_dataset(name="elevation"))
    with pytest.raises(qota.Error, match="no band 2"):
        qota.Terrain.from_raster(da, band=2)
    with pytest.raises(qota.Error, match="dimensions"):
        qota.Terrain.from_raster(da.expand_dims(time=[0]))
    with pytest.raises(qota.Error, match="DataArray"):
        qota.Terrain.from_xarray(np.zeros((3, 3)))
    with pytest.raises(qota.Error, match="azimuth"):
        qota.shadow(da)
    ds = rasterio.open(RAINIER)
    ds.close()
    with pytest.raises(qota.Error, match="closed"):
        qota.Terrain.from_raster(ds)
    with rasterio.open(RAINIER) as ds:
        with pytest.raises(qota.Error, match="no band 3"):
            qota.shadow(ds, azimuth=1, altitude=2, band=3)
    with pytest.raises(qota.Error, match="expected a path"):
        qota.Terrain.from_raster(42)


def test_rasterio_and_xarray_are_imported_only_when_used():
    code = ("import sys, qota; t = qota.Terrain.from_array([[1.0, 2.0], [3.0, 4.0]], (0, 1, 0, 2, 0, -1)); "
            "assert t.heights(0.9, 1.2) == t.heights(0.9, 1.2); "
            "print(sorted(m for m in ('rasterio', 'xarray', 'rioxarray') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd="/")
    assert out.stdout.strip() == "[]"
