"""qota.dask on a LocalCluster of two worker processes: shadows and hours of sunlight computed
block by block equal qota.shadow of the same raster pixel for pixel (suns low and high, blocks of
two sizes, voids across block edges; the tiles made from the file and from the array), heights
under points equal Terrain.from_raster's bit for bit, results written to GeoTIFF and Zarr read
back the same, and what cannot be done exactly is refused with a clear qota.Error."""
import logging
import os
import warnings

import numpy as np
import pytest

import qota
from test_interop import DATA, NODATA, RAINIER, assert_same_grid

xr = pytest.importorskip("xarray")
rioxarray = pytest.importorskip("rioxarray")
rasterio = pytest.importorskip("rasterio")
dd = pytest.importorskip("dask.dataframe")
distributed = pytest.importorskip("distributed")
import dask.array as dsa  # noqa: E402
import pandas as pd  # noqa: E402
import qota.dask  # noqa: E402
from rasterio.windows import Window  # noqa: E402

SUNS = ((315, 6), (100, 35))
pytestmark = pytest.mark.filterwarnings("ignore:make_current is deprecated:DeprecationWarning")  # tornado, under distributed
HOURS = dict(time="2024-06-21", tz="America/Los_Angeles", hours=(6, 20, 1.5))


@pytest.fixture(scope="module")
def client():
    """Two worker processes of one thread each; failed tasks' warnings silenced (errors are
    expected in the refusals)."""
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                                  silence_logs=logging.ERROR) as cluster, distributed.Client(cluster) as c:
        yield c


@pytest.fixture(scope="module")
def part(tmp_path_factory):
    """A part of the Rainier DEM (ridges and valleys south-east of the summit) with voids across
    where blocks of 64 and 100 pixels meet: a round one, a long thin one along a row, and scattered
    pixels."""
    with rasterio.open(RAINIER) as ds:
        window = Window(400, 450, 300, 260)
        z = ds.read(1, window=window).astype(np.float32)
        profile = dict(driver="GTiff", width=300, height=260, count=1, dtype="float32", crs=ds.crs,
                       transform=ds.window_transform(window), nodata=NODATA)
    r, c = np.mgrid[0:260, 0:300]
    z[z == -32768] = NODATA
    z[np.hypot(c - 64, r - 100) < 7] = NODATA
    z[128, 20:280] = NODATA
    z[(c * 7919 + r * 104729) % 97 == 0] = NODATA
    path = tmp_path_factory.mktemp("dask") / "part.tif"
    with rasterio.open(path, "w", **profile) as out:
        out.write(z, 1)
    return path


def test_shadows_by_blocks_equal_the_whole_rasters(client, part):
    for chunks in (64, 100):
        dem = rioxarray.open_rasterio(part, chunks=chunks)
        for azimuth, altitude in SUNS:
            want = qota.shadow(part, azimuth, altitude)
            assert (want == 0).sum() > 1000 and (want == 255).sum() > 1000 and (want == 128).sum() > 100
            got = qota.dask.shadow(dem, azimuth=azimuth, altitude=altitude)
            assert got.chunks == dem.chunks
            assert_same_grid(got, dem)
            np.testing.assert_array_equal(got.values[0], want, err_msg=f"blocks of {chunks}, sun {azimuth}/{altitude}")


def test_suns_at_and_below_the_horizon_on_the_ellipsoid(client, part):
    # Their shadows reach past the blocks' tangent planes, not past the body's curve: the blocks'
    # overlap comes from the ball that holds all terrain (ShadowTiles's halo).
    dem = rioxarray.open_rasterio(part, chunks=100)
    for azimuth, altitude in ((270, 0.0), (280, -0.3)):
        want = qota.shadow(part, azimuth, altitude)
        assert (want == 255).sum() > 100  # (high pixels see a sun below the centre's horizon)
        got = qota.dask.shadow(dem, azimuth=azimuth, altitude=altitude)
        np.testing.assert_array_equal(got.values[0], want, err_msg=f"sun {azimuth}/{altitude}")


def test_sunlight_hours_and_the_sun_at_a_time(client, part):
    want = qota.shadow(part, **HOURS)
    assert want.dtype == np.float32 and (want == -1).any() and len(np.unique(want)) > 5
    whole = qota.shadow(rioxarray.open_rasterio(part), **HOURS)  # a DataArray's: nodata -1
    assert whole.rio.nodata == -1 and whole.name == "sunlight_hours"
    np.testing.assert_array_equal(whole.values[0], want)
    for chunks in (64, 100):
        got = qota.dask.shadow(rioxarray.open_rasterio(part, chunks=chunks), **HOURS)
        assert got.dtype == np.float32 and got.rio.nodata == -1
        np.testing.assert_array_equal(got.values[0], want, err_msg=f"blocks of {chunks}")
    dem = rioxarray.open_rasterio(part, chunks=100).squeeze("band")
    at = dict(time="2024-06-21T18:30", tz="America/Los_Angeles")
    got = qota.dask.shadow(dem, **at)
    assert got.dims == ("y", "x")
    np.testing.assert_array_equal(got.values, qota.shadow(part, **at))


def test_tiles_from_the_file_or_the_arrays_own_heights(client, part):
    # A masked DataArray still has the file's values, grid, nodata and unit: its tiles read the
    # file. One converted (astype) no longer names its file, and one given another unit is not
    # the file's heights: the pass over the heights reads the array through Dask. The pixels are
    # qota.shadow's of the same DataArray either way.
    for dem, made_from in ((rioxarray.open_rasterio(part, chunks=100, masked=True), "file"),
                           (rioxarray.open_rasterio(part, chunks=64).astype("f8"), "array"),
                           (rioxarray.open_rasterio(part, chunks=100).assign_attrs(units="ft"), "array")):
        tiles = qota.dask.tiles(dem)
        assert tiles.heights_from == made_from
        got = qota.dask.shadow(dem, azimuth=315, altitude=6, tiles=tiles)
        np.testing.assert_array_equal(got.values, qota.shadow(dem.compute(), azimuth=315, altitude=6).values)
    dem = rioxarray.open_rasterio(part, chunks=64)
    got = qota.dask.shadow(dem, **HOURS, heights_from="array")
    np.testing.assert_array_equal(got.values[0], qota.shadow(part, **HOURS))


def test_results_written_to_geotiff_and_zarr(client, part, tmp_path):
    dem = rioxarray.open_rasterio(part, chunks=64)
    want = qota.shadow(part, azimuth=100, altitude=35)
    mask = qota.dask.shadow(dem, azimuth=100, altitude=35)
    qota.dask.to_geotiff(mask, tmp_path / "shadow.tif", compress="deflate")
    with rasterio.open(tmp_path / "shadow.tif") as back:
        np.testing.assert_array_equal(back.read(1), want)
        assert back.nodata == 128 and back.crs == dem.rio.crs and back.transform == dem.rio.transform()
        assert back.profile["tiled"]
    pytest.importorskip("zarr")
    qota.dask.to_zarr(mask, tmp_path / "shadow.zarr")
    back = xr.open_zarr(tmp_path / "shadow.zarr", mask_and_scale=False)["shadow"]  # 128 kept, not NaN
    np.testing.assert_array_equal(back.values[0], want)
    qota.dask.to_zarr(mask, tmp_path / "shadow.zarr")  # a store already there is replaced
    np.testing.assert_array_equal(xr.open_zarr(tmp_path / "shadow.zarr", mask_and_scale=False)["shadow"].values[0],
                                  want)


def test_a_failed_block_leaves_the_output_as_it_was(client, wide_void, tmp_path):
    # A void too wide for the margin makes some blocks fail: the files that were there before stay
    # whole (a half-written GeoTIFF of nodata replaced them before), and nothing else is left.
    mask = qota.dask.shadow(rioxarray.open_rasterio(wide_void, chunks=64), azimuth=100, altitude=35, void_margin=0)
    tif, store = tmp_path / "shadow.tif", tmp_path / "shadow.zarr"
    tif.write_bytes(b"OLD")
    with pytest.raises(qota.Error, match="larger overlap"):
        qota.dask.to_geotiff(mask, tif)
    assert tif.read_bytes() == b"OLD"
    with pytest.raises(qota.Error, match="would not be the ones computed"):
        qota.dask.to_geotiff(mask, tif, compress="jpeg")
    pytest.importorskip("zarr")
    store.mkdir()
    (store / "kept").write_bytes(b"OLD")
    with pytest.raises(qota.Error, match="larger overlap"):
        qota.dask.to_zarr(mask, store)
    assert (store / "kept").read_bytes() == b"OLD"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["shadow.tif", "shadow.zarr"]


def test_points_equal_the_whole_terrain(client):
    # Random points, pixel centres, the outer half pixel, off the raster and not finite.
    rng = np.random.default_rng(19)
    terrain = qota.Terrain.from_raster(RAINIER)
    with rasterio.open(RAINIER) as ds:
        t, w, h = ds.transform, ds.width, ds.height
    cols, rows = rng.integers(0, w, 500), rng.integers(0, h, 500)
    cx, cy = t * (cols + 0.5, rows + 0.5)
    x = np.concatenate([rng.uniform(t.c - 0.01, t.c + w * t.a + 0.01, 6000), cx, [t.c + 0.1 * t.a, np.nan]])
    y = np.concatenate([rng.uniform(t.f + h * t.e - 0.01, t.f + 0.01, 6000), cy, [t.f + 0.2 * t.e, 46.5]])
    want = terrain.heights(x, y)
    assert np.isnan(want).sum() > 50 and (~np.isnan(want)).sum() > 5000
    points = pd.DataFrame({"x": x, "y": y, "id": np.arange(len(x))})
    frame = dd.from_pandas(points, npartitions=5)
    got = qota.dask.sample(RAINIER, frame).compute()
    assert got.name == "height" and got.index.equals(points.index)
    np.testing.assert_array_equal(got.to_numpy(), want)
    shuffled = qota.dask.sample(RAINIER, frame, by_block=True, block=256)
    assert shuffled.npartitions == frame.npartitions
    got = shuffled.compute()
    assert got.index.equals(points.index)
    np.testing.assert_array_equal(got.to_numpy(), want)
    array = dsa.from_array(np.column_stack([x, y]), chunks=(1700, 2))
    np.testing.assert_array_equal(qota.dask.sample(RAINIER, array).compute(), want)
    # GDAL's rules through Dask: qota.sample's answers
    for rule in ("nearest", "cubic"):
        got = qota.dask.sample(RAINIER, dd.from_pandas(points, npartitions=3), resampling=rule).compute()
        np.testing.assert_array_equal(got.to_numpy(), qota.sample(RAINIER, x, y, resampling=rule))
    # By block, whatever the index: values repeated (4 rows each, sorted), shuffled, not numbers,
    # or unknown divisions: every height on its own row.
    n = len(x)
    for index in (np.repeat(np.arange(n // 4 + 1), 4)[:n], rng.permutation(n), np.array([f"p{i % 977}" for i in range(n)])):
        points = pd.DataFrame({"x": x, "y": y}, index=index)
        for frame in (dd.from_pandas(points, npartitions=4, sort=False), dd.from_pandas(points, npartitions=3)):
            got = qota.dask.sample(RAINIER, frame, by_block=True, block=64).compute()
            expected = pd.Series(terrain.heights(frame.x.compute().to_numpy(), frame.y.compute().to_numpy()),
                                 index=frame.index.compute())
            assert got.index.equals(expected.index)
            np.testing.assert_array_equal(got.to_numpy(), expected.to_numpy())



def test_a_raster_rewritten_between_calls_is_read_again(client, tmp_path):
    # Workers keep a call's samplers and their tiles; a later call after the file was rewritten
    # (or replaced) reads the new heights, and a file rewritten after a call but before its
    # computation is refused, not answered from either version. (Flat rasters: the heights are
    # known by construction, and on a plane every pixel sees both observers.)
    path = tmp_path / "flat.tif"

    def write(value, replace):
        target = tmp_path / "next.tif" if replace else path
        profile = dict(driver="GTiff", width=40, height=30, count=1, dtype="float32", crs="EPSG:32610",
                       transform=rasterio.transform.from_origin(500000, 5000030, 1, 1))
        with rasterio.open(target, "w", **profile) as out:
            out.write(np.full((30, 40), value, np.float32), 1)
        if replace:
            os.replace(target, path)

    points = dsa.from_array(np.array([[500000.5 + i, 5000029.5 - i] for i in range(20)]), chunks=(5, 2))
    write(10.0, replace=False)
    np.testing.assert_array_equal(qota.dask.sample(path, points).compute(), 10.0)
    write(99.0, replace=True)
    np.testing.assert_array_equal(qota.dask.sample(path, points).compute(), 99.0)
    write(-4.5, replace=False)
    np.testing.assert_array_equal(qota.dask.sample(path, points, resampling="nearest").compute(), -4.5)
    lazy = qota.dask.sample(path, points)
    geo = pytest.importorskip("geopandas")
    places = geo.GeoDataFrame(geometry=geo.points_from_xy([500003.5, 500010.5], [5000020.5, 5000001.5]),
                              crs="EPSG:32610")
    lazy_frame = qota.dask.sample(path, places)
    write(7.0, replace=True)
    with pytest.raises(qota.Error, match="changed after qota.dask.sample was called"):
        lazy.compute()
    with pytest.raises(qota.Error, match="changed after qota.dask.sample was called"):
        lazy_frame.compute()
    np.testing.assert_array_equal(qota.dask.sample(path, points).compute(), 7.0)
    # A process keeps one sampler a raster, the latest call's (each holds up to 128 MiB of tiles).
    qota.dask._samplers.clear()
    with warnings.catch_warnings():  # (the synchronous scheduler beside the client: on purpose)
        warnings.simplefilter("ignore", UserWarning)
        for _ in range(5):
            np.testing.assert_array_equal(qota.dask.sample(path, points).compute(scheduler="sync"), 7.0)
    assert len(qota.dask._samplers) == 1
    # Cumulative viewsheds likewise: counted on the raster the call described, or refused.
    observers = np.array([[500005.5, 5000005.5], [500030.5, 5000020.5]])
    counts = qota.dask.viewsheds(path, observers, flat=True, per_task=1)
    write(8.0, replace=True)
    with pytest.raises(qota.Error, match="changed after qota.dask.viewsheds was called"):
        counts.compute()
    np.testing.assert_array_equal(qota.dask.viewsheds(path, observers, flat=True, per_task=1).compute(), 2)


def test_a_vrt_whose_source_changed_after_the_call_is_refused(client, tmp_path):
    # A VRT mosaic of two tiles: a tile rewritten after a call and before its computation (the
    # VRT itself untouched) is refused, naming the tile, as a rewritten raster is; the next call
    # reads the new heights. (Flat tiles: the heights at their pixel centres are known.)
    gdal = pytest.importorskip("osgeo.gdal")

    def tile(name, x0, value):
        profile = dict(driver="GTiff", width=20, height=30, count=1, dtype="float32", crs="EPSG:32610",
                       transform=rasterio.transform.from_origin(x0, 5000030, 1, 1))
        with rasterio.open(tmp_path / name, "w", **profile) as out:
            out.write(np.full((30, 20), value, np.float32), 1)

    tile("a.tif", 500000, 10.0)
    tile("b.tif", 500020, 20.0)
    vrt = tmp_path / "mosaic.vrt"
    mosaic = gdal.BuildVRT(str(vrt), [str(tmp_path / "a.tif"), str(tmp_path / "b.tif")])
    mosaic = None  # noqa: F841 (written when closed)
    points = dsa.from_array(np.array([[500005.5, 5000010.5], [500025.5, 5000010.5]]), chunks=(1, 2))
    np.testing.assert_array_equal(qota.dask.sample(vrt, points).compute(), [10.0, 20.0])
    lazy = qota.dask.sample(vrt, points)
    tile("b.tif", 500020, 30.0)
    with pytest.raises(qota.Error, match=r"b\.tif\) changed after qota\.dask\.sample was called"):
        lazy.compute()
    np.testing.assert_array_equal(qota.dask.sample(vrt, points).compute(), [10.0, 30.0])


def test_geodataframes_through_dask(client):
    gpd = pytest.importorskip("geopandas")
    # Points in UTM (the frame's CRS, not the raster's), some empty and off the raster; nearest:
    # the value rasterio reads in the pixel containing each point's longitude and latitude.
    rng = np.random.default_rng(23)
    with rasterio.open(RAINIER) as ds:
        t, values = ds.transform, ds.read(1).astype(np.float64)
    lon = rng.uniform(t.c + 0.01, t.c + 1 - 0.01, 3000)
    lat = rng.uniform(t.f - 1 + 0.01, t.f - 0.01, 3000)
    cols, rows = ~t * (lon, lat)
    want = values[rows.astype(int), cols.astype(int)]
    want[want == -32768] = np.nan
    frame = gpd.GeoDataFrame({"id": np.arange(3000)}, geometry=gpd.points_from_xy(lon, lat), crs="EPSG:4326")
    frame = frame.to_crs("EPSG:32610")
    frame.loc[[5, 6], "geometry"] = gpd.points_from_xy([0.0, None], [0.0, None], crs="EPSG:32610")
    want[[5, 6]] = np.nan
    lazy = qota.dask.sample(RAINIER, dd.from_pandas(frame, npartitions=4), resampling="nearest", field="elev")
    assert lazy.npartitions == 4 and list(lazy.columns) == ["id", "geometry", "elev"]
    got = lazy.compute()
    assert isinstance(got, gpd.GeoDataFrame) and got.crs == frame.crs and got.index.equals(frame.index)
    near_edge = np.isclose(cols % 1, 0, atol=1e-6) | np.isclose(rows % 1, 0, atol=1e-6)  # (UTM round trip)
    np.testing.assert_array_equal(got["elev"].to_numpy()[~near_edge], want[~near_edge])
    assert np.isnan(want).sum() >= 2 and (~np.isnan(want)).sum() > 2900
    # A GeoDataFrame itself is split into partitions of chunksize rows; the triangle rule is
    # qota.sample's.
    lazy = qota.dask.sample(RAINIER, frame, chunksize=1000)
    assert lazy.npartitions == 3
    np.testing.assert_array_equal(lazy.compute()["height"].to_numpy(), qota.sample(RAINIER, frame)["height"].to_numpy())
    with pytest.raises(qota.Error, match="already has a column"):
        qota.dask.sample(RAINIER, got, field="elev")
    with pytest.raises(qota.Error, match="by_block"):
        qota.dask.sample(RAINIER, frame, by_block=True)

@pytest.fixture(scope="module")
def wide_void(part, tmp_path_factory):
    """The part with a void 120 pixels across: its fill reaches 60 pixels in, farther than a block's
    window without a void margin."""
    with rasterio.open(part) as ds:
        z, profile = ds.read(1), ds.profile
    r, c = np.mgrid[0:z.shape[0], 0:z.shape[1]]
    z[np.hypot(c - 150, r - 130) < 60] = NODATA
    path = tmp_path_factory.mktemp("void") / "wide_void.tif"
    with rasterio.open(path, "w", **profile) as out:
        out.write(z, 1)
    return path


def test_refusals(client, part, wide_void):
    dem = rioxarray.open_rasterio(part, chunks=64)
    # Voids wider than the margin near a block edge: refused when the block is computed, naming
    # what it needs.
    with pytest.raises(qota.Error, match="larger overlap"):
        qota.dask.shadow(rioxarray.open_rasterio(wide_void, chunks=64), azimuth=100, altitude=35,
                         void_margin=0).compute()
    with pytest.raises(qota.Error, match="give azimuth and altitude, or time"):
        qota.dask.shadow(dem, azimuth=315)
    with pytest.raises(qota.Error, match="one light"):
        qota.dask.shadow(dem, azimuth=315, altitude=6, time="2024-06-21T12:00Z")
    with pytest.raises(qota.Error, match="hours needs time"):
        qota.dask.shadow(dem, azimuth=315, altitude=6, hours=(6, 20, 1))
    with pytest.raises(qota.Error, match="at least one minute"):
        qota.dask.shadow(dem, hours=(6, 20, 0.001), time="2024-06-21", tz="UTC")
    with pytest.raises(qota.Error, match="altitude must be between"):
        qota.dask.shadow(dem, azimuth=315, altitude=91)
    with pytest.raises(qota.Error, match="not chunked"):
        qota.dask.shadow(rioxarray.open_rasterio(part), azimuth=315, altitude=6)
    with pytest.raises(qota.Error, match="another raster"):
        qota.dask.shadow(dem.isel(x=slice(0, 200)), azimuth=315, altitude=6, tiles=qota.dask.tiles(dem))
    with pytest.raises(qota.Error, match="heights_from"):
        qota.dask.shadow(dem.astype("f8"), azimuth=315, altitude=6, heights_from="file")
    with pytest.raises(qota.Error, match="no column 'lon'"):
        qota.dask.sample(RAINIER, dd.from_pandas(pd.DataFrame({"x": [0.0], "y": [0.0]}), npartitions=1), x="lon")
    with pytest.raises(FileNotFoundError):
        qota.dask.sample(DATA / "no_such.tif", dsa.zeros((3, 2)))


def test_tiles_given_are_checked_against_the_call(client, part, tmp_path):
    # Tiles of another raster on the same grid, of another band or z_factor: refused (before, no
    # error and thousands of pixels wrong; z_factor was ignored).
    dem = rioxarray.open_rasterio(part, chunks=100)
    flat_path = tmp_path / "flat.tif"
    with rasterio.open(part) as ds:
        profile = ds.profile
        with rasterio.open(flat_path, "w", **profile) as out:
            out.write(np.full((ds.height, ds.width), 700, np.float32), 1)
    other = qota.dask.tiles(rioxarray.open_rasterio(flat_path, chunks=100))
    with pytest.raises(qota.Error, match="are not those the shadow tiles were made from"):
        qota.dask.shadow(dem, azimuth=90, altitude=5, tiles=other).compute()
    mine = qota.dask.tiles(dem)
    with pytest.raises(qota.Error, match="z_factor=1.0, this call asks z_factor=2.0"):
        qota.dask.shadow(dem, azimuth=90, altitude=5, z_factor=2, tiles=mine)
    two = xr.concat([dem, dem + 1], dim="band").assign_coords(band=[1, 2])
    with pytest.raises(qota.Error, match="band 1, this call asks band=2"):
        qota.dask.shadow(two, azimuth=90, altitude=5, band=2, tiles=qota.dask.tiles(two, band=1))
    with pytest.raises(qota.Error, match="these tiles are given"):
        qota.dask.shadow(dem, azimuth=90, altitude=5, heights_from="array", tiles=mine)
    # z_factor honoured with tiles made with it.
    got = qota.dask.shadow(dem, azimuth=90, altitude=5, z_factor=2, tiles=qota.dask.tiles(dem, z_factor=2))
    np.testing.assert_array_equal(got.values[0], qota.shadow(part, azimuth=90, altitude=5, z_factor=2))
    # A DataArray whose values were changed after it was read, with the file's tiles: refused,
    # naming the cause and what to give.
    changed = dem.copy(data=dem.data + 50)
    with pytest.raises(qota.Error, match="heights_from='array'"):
        qota.dask.shadow(changed, azimuth=90, altitude=5, tiles=mine).compute()


def test_chunks_smaller_than_the_halo_are_merged(client):
    # Chunks of 7 x 13 pixels at a sun whose halo spans hundreds: before, no result in 150 s and a
    # client of 4.7 GB; the blocks are now merged, and the pixels are qota.shadow's.
    dem = rioxarray.open_rasterio(DATA / "SainteHelens.dem", chunks={"y": 7, "x": 13})
    mask = qota.dask.shadow(dem, 135, 20)
    assert mask.chunks == dem.chunks
    assert len(mask.data.__dask_graph__()) < 20000
    np.testing.assert_array_equal(mask.values[0], qota.shadow(DATA / "SainteHelens.dem", 135, 20))


def test_max_memory_sizes_the_blocks(client, part):
    # A budget smaller than the chunks' tasks: smaller blocks that fit, the same pixels.
    dem = rioxarray.open_rasterio(part, chunks=300)
    whole = qota.dask.shadow(dem, azimuth=135, altitude=40)
    small = qota.dask.shadow(dem, azimuth=135, altitude=40, max_memory="4M")
    assert small.attrs["qota_task_memory"] <= 4 << 20 < whole.attrs["qota_task_memory"]
    assert small.chunks == dem.chunks
    np.testing.assert_array_equal(small.values[0], qota.shadow(part, azimuth=135, altitude=40))
    with pytest.raises(qota.Error, match="even blocks of 16 pixels"):
        qota.dask.shadow(dem, azimuth=135, altitude=2, max_memory=1 << 20)
    with pytest.raises(qota.Error, match="not a size"):
        qota.dask.shadow(dem, azimuth=135, altitude=40, max_memory="lots")


def test_viewsheds_count_the_single_viewsheds(client):
    # Five observers in groups of two (three tasks) within 10 km: each pixel's count is how many
    # of qota.viewshed's single masks see it (an independent path: one observer at a time, a
    # window of the raster each), voids VIEWSHED_NODATA.
    points = np.loadtxt(DATA / "rainier_lookouts.txt")
    got = qota.dask.viewsheds(RAINIER, points, max_distance=10000, per_task=2)
    assert isinstance(got, dsa.Array) and got.dtype == np.uint32
    got = got.compute()
    want = np.zeros(got.shape, dtype=np.int64)
    for x, y, h in points:
        seen = qota.viewshed(RAINIER, observer=(x, y), observer_height=h, max_distance=10000)
        want += seen == 255
        voids = seen == 128
    want[voids] = qota.dask.VIEWSHED_NODATA
    np.testing.assert_array_equal(got, want)
    assert (got[~voids] >= 1).sum() > 1000
    with pytest.raises(qota.Error, match="observers must be"):
        qota.dask.viewsheds(RAINIER, np.zeros((0, 2)))
    # Bad observers are refused on the client, before a graph is made.
    high = points.copy()
    high[3, 2] = 1e300
    with pytest.raises(qota.Error, match=r"observers\[3\]: the height must be a number of metres from 0 to 1e9"):
        qota.dask.viewsheds(RAINIER, high)
    high[3, 2], high[1, 0] = 2, np.nan
    with pytest.raises(qota.Error, match=r"observers\[1\]: x, y must be finite"):
        qota.dask.viewsheds(RAINIER, high)
    with pytest.raises(qota.Error, match="target_height must be"):
        qota.dask.viewsheds(RAINIER, points, target_height=-1)
