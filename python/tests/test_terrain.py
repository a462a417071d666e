"""qota's Python package against independent computations: a numpy brute force over the
triangles, GDAL's own reading of the raster, exact planes."""
import os
import threading
from pathlib import Path

import numpy as np
import pytest

import qota

DATA = Path(os.environ.get("QOTA_DATA_DIR", Path(__file__).resolve().parents[2] / "data"))
RAINIER = DATA / "mt_rainier_90m.tif"


def brute_force(vertices, triangles, x, y, z=None, below=True):
    """Per point: the nearest height at or below z (or above) over every triangle containing
    (x, y) strictly inside (barycentric coordinates > eps), NaN if none; and whether the point is
    near an edge (then either answer may come)."""
    out = np.full(x.shape, np.nan)
    near = np.zeros(x.shape, bool)
    for tri in triangles:
        a, b, c = vertices[tri]
        d = (b[1] - c[1]) * (a[0] - c[0]) + (c[0] - b[0]) * (a[1] - c[1])
        if d == 0:
            continue
        l1 = ((b[1] - c[1]) * (x - c[0]) + (c[0] - b[0]) * (y - c[1])) / d
        l2 = ((c[1] - a[1]) * (x - c[0]) + (a[0] - c[0]) * (y - c[1])) / d
        l3 = 1 - l1 - l2
        m = np.minimum(np.minimum(l1, l2), l3)
        near |= np.abs(m) < 1e-9
        inside = m > 1e-9
        h = l1 * a[2] + l2 * b[2] + l3 * c[2]
        if z is not None:
            inside &= (h <= z) if below else (h >= z)
        take = inside & (np.isnan(out) | ((h > out) if (z is None or below) else (h < out)))
        out[take] = h[take]
    return out, near


def layered_mesh(rng):
    """A jittered grid of triangles (a heightfield) and a second, higher layer over part of it."""
    n = 12
    gx, gy = np.meshgrid(np.arange(n, dtype=float), np.arange(n, dtype=float))
    v = np.column_stack([gx.ravel() + rng.uniform(-0.3, 0.3, n * n), gy.ravel() + rng.uniform(-0.3, 0.3, n * n),
                         rng.uniform(0, 5, n * n)])
    tris = []
    for r in range(n - 1):
        for c in range(n - 1):
            i = r * n + c
            tris += [[i, i + 1, i + n + 1], [i, i + n + 1, i + n]]
    upper = v[: n * 6].copy()
    upper[:, 2] += 20
    v = np.vstack([v, upper])
    tris += [[t[0] + n * n, t[1] + n * n, t[2] + n * n] for t in tris[: 2 * (n - 1) * 5]]
    return v, np.array(tris)


def test_version():
    assert qota.__version__ == "0.2.0"


def test_mesh_queries_match_the_brute_force():
    rng = np.random.default_rng(1)
    v, t = layered_mesh(rng)
    terrain = qota.Terrain.from_mesh(v, t)
    x, y = rng.uniform(-1, 12, 4000), rng.uniform(-1, 12, 4000)
    z = rng.uniform(-2, 30, 4000)
    for got, (want, near) in [
        (terrain.heights(x, y), brute_force(v, t, x, y)),
        (terrain.below(x, y, z), brute_force(v, t, x, y, z, True)),
        (terrain.above(x, y, z), brute_force(v, t, x, y, z, False)),
    ]:
        clear = ~near
        assert np.count_nonzero(clear) > 3900
        np.testing.assert_array_equal(np.isnan(got[clear]), np.isnan(want[clear]))
        np.testing.assert_allclose(got[clear & ~np.isnan(want)], want[clear & ~np.isnan(want)], rtol=0, atol=1e-9)
    lo, hi = terrain.bracket(x, y, z)
    np.testing.assert_array_equal(lo, terrain.below(x, y, z))
    np.testing.assert_array_equal(hi, terrain.above(x, y, z))


def test_all_lists_every_layer_top_first():
    rng = np.random.default_rng(2)
    v, t = layered_mesh(rng)
    terrain = qota.Terrain.from_mesh(v, t)
    hits = terrain.all(3.3, 2.2)  # under the upper layer
    assert len(hits) == 2 and hits[0][0] > hits[1][0] + 10
    height, polygon, normal = hits[0]
    assert 0 <= polygon < len(t) and abs(np.linalg.norm(normal) - 1) < 1e-12 and normal[2] > 0
    assert terrain.all(50, 50) == []


def test_shapes_broadcast_and_nan_means_no_terrain():
    v = np.array([[0, 0, 100], [10, 0, 100], [10, 10, 100], [0, 10, 100]], float)
    terrain = qota.Terrain.from_mesh(v, [[0, 1, 2], [0, 2, 3]])
    h = terrain.heights(np.full((3, 4), 2.0), 7.0)
    assert h.shape == (3, 4) and np.all(h == 100)
    assert np.isnan(terrain.heights(20.0, 5.0))
    assert np.isnan(terrain.heights(np.nan, 5.0))
    assert terrain.below([2.0], [7.0], [50.0]).tolist() == [pytest.approx(np.nan, nan_ok=True)]
    assert terrain.above([2.0], [7.0], [50.0]).tolist() == [100.0]


def test_array_is_the_raster_gdal_reads():
    from osgeo import gdal

    ds = gdal.Open(str(RAINIER))
    band = ds.GetRasterBand(1)
    heights = band.ReadAsArray().astype(np.float64)
    gt = ds.GetGeoTransform()
    from_array = qota.Terrain.from_array(heights, gt, nodata=band.GetNoDataValue())
    from_raster = qota.Terrain.from_raster(RAINIER)
    rng = np.random.default_rng(3)
    rows, cols = rng.integers(1, heights.shape[0] - 1, 4000), rng.integers(1, heights.shape[1] - 1, 4000)
    # Centres with valid neighbours all round (a centre on a hole's outline may go either way).
    valid = heights != band.GetNoDataValue()
    keep = np.ones(rows.shape, bool)
    for dr in (-1, 0, 1):
        for dc in (-1, 0, 1):
            keep &= valid[rows + dr, cols + dc]
    rows, cols = rows[keep], cols[keep]
    assert rows.size > 1000
    # Pixel centres carry the vertices: the height there is the pixel's value, as GDAL reads it.
    x = gt[0] + (cols + 0.5) * gt[1] + (rows + 0.5) * gt[2]
    y = gt[3] + (cols + 0.5) * gt[4] + (rows + 0.5) * gt[5]
    np.testing.assert_allclose(from_raster.heights(x, y), heights[rows, cols], rtol=0, atol=1e-6)
    np.testing.assert_allclose(from_array.heights(x, y), heights[rows, cols], rtol=0, atol=1e-6)
    # Between centres the same terrain from both.
    px, py = x + rng.uniform(0.1, 0.4, rows.size) * gt[1], y + rng.uniform(0.1, 0.4, rows.size) * gt[5]
    np.testing.assert_array_equal(from_array.heights(px, py), from_raster.heights(px, py))


class Affine:
    """What rasterio's affine.Affine offers: x = a col + b row + c, y = d col + e row + f."""

    def __init__(self, a, b, c, d, e, f):
        self.a, self.b, self.c, self.d, self.e, self.f = a, b, c, d, e, f


def test_array_plane_is_exact_and_nodata_are_holes():
    # z = 2 x + 3 y + 1 at the pixel centres of a 30 x 20 grid, origin (100, 50), 2 by -2 pixels.
    rows, cols = 20, 30
    cx = 100 + 2 * (np.arange(cols) + 0.5)
    cy = 50 - 2 * (np.arange(rows) + 0.5)
    z = 2 * cx[None, :] + 3 * cy[:, None] + 1
    z[7, 9] = -9999
    for transform in [(100, 2, 0, 50, 0, -2), Affine(2, 0, 100, 0, -2, 50)]:
        terrain = qota.Terrain.from_array(z, transform, nodata=-9999)
        rng = np.random.default_rng(4)
        x, y = rng.uniform(cx[0], cx[-1], 3000), rng.uniform(cy[-1], cy[0], 3000)
        h = terrain.heights(x, y)
        # The triangles around the nodata centre are holes; they cover the diamond within one
        # pixel of it (|dx| + |dy| < 1 pixel), and nothing beyond the four squares around it.
        dx, dy = np.abs(x - cx[9]) / 2, np.abs(y - cy[7]) / 2
        assert np.all(np.isnan(h[dx + dy < 0.999]))
        far = np.maximum(dx, dy) > 1.001
        assert np.count_nonzero(far) > 2900
        np.testing.assert_allclose(h[far], 2 * x[far] + 3 * y[far] + 1, rtol=1e-12)
        between = ~far & ~np.isnan(h)
        np.testing.assert_allclose(h[between], 2 * x[between] + 3 * y[between] + 1, rtol=1e-12)


def test_save_and_load_answer_alike(tmp_path):
    rng = np.random.default_rng(5)
    v, t = layered_mesh(rng)
    terrain = qota.Terrain.from_mesh(v, t)
    terrain.save(tmp_path / "t.qota")
    back = qota.Terrain.load(tmp_path / "t.qota")
    x, y = rng.uniform(0, 11, 1000), rng.uniform(0, 11, 1000)
    np.testing.assert_array_equal(back.heights(x, y), terrain.heights(x, y))


def test_errors_name_what_is_wrong(tmp_path):
    with pytest.raises(FileNotFoundError, match="nonexistent"):
        qota.Terrain.from_raster(tmp_path / "nonexistent.tif")
    with pytest.raises(OSError):
        qota.Terrain.load(tmp_path / "nonexistent.qota")
    (tmp_path / "empty.tif").write_bytes(b"")
    with pytest.raises(qota.Error, match="empty.tif"):
        qota.Terrain.from_raster(tmp_path / "empty.tif")
    with pytest.raises(qota.Error, match="names vertex 7"):
        qota.Terrain.from_mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 7]])
    with pytest.raises(qota.Error, match=r"\(N, 3\)"):
        qota.Terrain.from_mesh([[0, 0], [1, 0]], [[0, 1, 1]])
    with pytest.raises(qota.Error, match="6 numbers"):
        qota.Terrain.from_array(np.zeros((2, 2)), (0, 1, 0, 0))
    with pytest.raises(qota.Error, match="singular"):
        qota.Terrain.from_array(np.zeros((2, 2)), (0, 0, 0, 0, 0, 0))
    with pytest.raises(qota.Error, match="not finite"):
        qota.Terrain.from_mesh([[0, 0, np.inf], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    with pytest.raises(qota.Error, match="integers"):
        qota.Terrain.from_mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0.0, 1.7, 2.0]])
    with pytest.raises(qota.Error, match="no band 5"):
        qota.Terrain.from_raster(RAINIER, band=5)
    with pytest.raises(qota.Error, match="QOTATREE"):
        qota.Terrain.load(RAINIER)
    with pytest.raises(ValueError):
        qota.Terrain.from_mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]]).heights(np.zeros(3), np.zeros(4))
    assert issubclass(qota.Error, ValueError)


def test_batches_run_while_other_threads_run():
    # The GIL is released during a batch: two threads' batches give the same answers as one.
    terrain = qota.Terrain.from_raster(RAINIER)
    rng = np.random.default_rng(6)
    x, y = rng.uniform(-122, -121.5, 200000), rng.uniform(46.6, 47, 200000)
    want = terrain.heights(x, y)
    got = [None, None]

    def run(i):
        got[i] = terrain.heights(x, y)

    threads = [threading.Thread(target=run, args=(i,)) for i in range(2)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    for g in got:
        np.testing.assert_array_equal(g, want)


def test_shadow_is_the_tools_mask(tmp_path):
    import subprocess

    from osgeo import gdal

    tool = os.environ.get("QOTA_TOOL", str(Path(__file__).resolve().parents[2] / "build" / "tools" / "qota"))
    if not Path(tool).exists():
        pytest.skip("no qota tool built at " + tool)
    subprocess.run([tool, "shadow", str(RAINIER), "-o", str(tmp_path / "tool.tif"), "-az", "135", "-alt", "20", "-q"],
                   check=True)
    ds = gdal.Open(str(tmp_path / "tool.tif"))  # (held: a band outliving its dataset crashes GDAL's bindings)
    want = ds.GetRasterBand(1).ReadAsArray()
    got = qota.shadow(RAINIER, azimuth=135, altitude=20)
    assert got.dtype == np.uint8 and got.shape == want.shape
    np.testing.assert_array_equal(got, want)
    assert set(np.unique(got)) <= {0, 128, 255} and (got == 0).any() and (got == 255).any()
    kept = qota.shadow(RAINIER, time="2024-06-21T18:30", tz="America/Los_Angeles", output=tmp_path / "t.tif")
    assert (tmp_path / "t.tif").exists() and kept.shape == want.shape
    with pytest.raises(qota.Error, match="azimuth"):
        qota.shadow(RAINIER)


def test_viewshed_is_the_tools_raster(tmp_path):
    import subprocess

    from osgeo import gdal

    tool = os.environ.get("QOTA_TOOL", str(Path(__file__).resolve().parents[2] / "build" / "tools" / "qota"))
    if not Path(tool).exists():
        pytest.skip("no qota tool built at " + tool)
    subprocess.run([tool, "viewshed", str(RAINIER), "--observer", "-121.78,46.83", "--oz", "10", "--md", "15000",
                    "-o", str(tmp_path / "tool.tif"), "-q"], check=True)
    ds = gdal.Open(str(tmp_path / "tool.tif"))
    want = ds.GetRasterBand(1).ReadAsArray()
    got = qota.viewshed(RAINIER, observer=(-121.78, 46.83), observer_height=10, max_distance=15000)
    assert got.dtype == np.uint8 and got.shape == want.shape
    np.testing.assert_array_equal(got, want)
    assert {0, 64, 255} <= set(np.unique(got)) <= {0, 64, 128, 255}
    with pytest.raises(qota.Error, match="observer_height"):
        qota.viewshed(RAINIER, observer=(-121.78, 46.83), observer_height=-1)
    for name in ("observer_height", "target_height"):  # beyond any terrain: refused at once
        with pytest.raises(qota.Error, match=f"{name} must be a number of metres from 0 to 1e9"):
            qota.viewshed(RAINIER, observer=(-121.78, 46.83), **{name: 1e300})
    with pytest.raises(qota.Error, match="not on"):
        qota.viewshed(RAINIER, observer=(-130, 46.83))
    # Refraction lets the observer see over more of the terrain (a triangle's corners are raised by
    # the model and its inside in between: a few grazing pixels may go the other way).
    bent = qota.viewshed(RAINIER, observer=(-121.78, 46.83), observer_height=10, max_distance=15000, refraction=0.13)
    gained, lost = ((bent == 255) & (got != 255)).sum(), ((bent != 255) & (got == 255)).sum()
    assert gained > 2 * lost and (bent == 255).sum() > (got == 255).sum()


def test_viewshed_of_a_wall(tmp_path):
    # A 10 m wall across column 6 of a flat 1 m grid, the observer 2 m up at column 2: every
    # pixel up to the wall's face is seen, none behind it (the line to column 7 passes the wall
    # at 2 - 2 * 4 / 5 m).
    heights = np.zeros((5, 12))
    heights[:, 6] = 10
    path = tmp_path / "wall.tif"
    qota._qota._write_raster(str(path), heights, (500000.0, 1.0, 0.0, 5000005.0, 0.0, -1.0), None, "EPSG:32633", "m")
    seen = qota.viewshed(path, observer=(500002.5, 5000002.5), flat=True)
    np.testing.assert_array_equal(seen[:, :7], 255)
    np.testing.assert_array_equal(seen[:, 7:], 0)


def test_sun_position_at_noon_on_the_solstice():
    # Greenwich (0, 51.4769) at 2024-06-21 12:00 UTC, two minutes before solar noon (the equation
    # of time is -1.7 min): altitude 90 - 51.4769 + 23.44 (the solstice's declination) = 61.96
    # degrees, plus 0.01 of refraction; the Sun within a degree of due south.
    az, alt = qota.sun_position("2024-06-21T12:00:00Z", 0.0, 51.4769)
    assert abs(alt - 61.96) < 0.05
    assert abs(az - 180) < 1.5
    with pytest.raises(qota.Error):
        qota.sun_position("2024-02-30T12:00Z", 0, 0)


def test_polygons_and_normals_on_request():
    rng = np.random.default_rng(7)
    v, t = layered_mesh(rng)
    terrain = qota.Terrain.from_mesh(v, t)
    x, y, z = rng.uniform(-1, 12, 3000), rng.uniform(-1, 12, 3000), rng.uniform(-2, 30, 3000)
    for name, below in [("below", True), ("above", False)]:
        h, p, n = terrain.hits(x, y, z, side=name)
        np.testing.assert_array_equal(h, getattr(terrain, name)(x, y, z))
        hit = ~np.isnan(h)
        assert np.all(p[~hit] == -1) and np.all(np.isnan(n[~hit]))
        # The polygon holds the point at that height (its plane, from its own corners), and the
        # normal is its unit normal, facing up.
        a, b, c = v[t[p[hit], 0]], v[t[p[hit], 1]], v[t[p[hit], 2]]
        normal = np.cross(b - a, c - a)
        normal /= np.linalg.norm(normal, axis=1)[:, None]
        normal *= np.sign(normal[:, 2])[:, None]
        np.testing.assert_allclose(n[hit], normal, atol=1e-9)
        point = np.column_stack([x[hit], y[hit], h[hit]])
        np.testing.assert_allclose(np.einsum("ij,ij->i", point - a, normal), 0, atol=1e-9)
    hit = terrain.hits(np.full((2, 3), 3.3), 2.2, normals=False)
    assert isinstance(hit, qota.Hits) and hit.normal is None
    assert hit.height.shape == hit.polygon.shape == (2, 3) and hit.polygon.dtype == np.int64
    lo, hi = terrain.hits(3.3, 2.2, 10.0, side="below"), terrain.hits(3.3, 2.2, 10.0, side="above")
    assert lo.height < 10 < hi.height and lo.normal.shape == hi.normal.shape == (3,)
    assert terrain.bracket(3.3, 2.2, 10.0) == (lo.height, hi.height)
    with pytest.raises(qota.Error, match="side must be"):
        terrain.hits(3.3, 2.2, 10.0, side="under")
    with pytest.raises(qota.Error, match="z is given"):
        terrain.hits(3.3, 2.2, 10.0)
    with pytest.raises(qota.Error, match="z is given"):
        terrain.hits(3.3, 2.2, side="below")
    # The 0.2 flags still answer, as a tuple, and say what replaces them.
    with pytest.warns(DeprecationWarning, match="use hits"):
        h, p = terrain.heights(np.full((2, 3), 3.3), 2.2, polygons=True)
    np.testing.assert_array_equal(p, hit.polygon)
    with pytest.warns(DeprecationWarning):
        (lo_h, lo_n), (hi_h, hi_n) = terrain.bracket(3.3, 2.2, 10.0, normals=True)
    np.testing.assert_array_equal(lo_n, lo.normal)


def test_outer_half_pixel_takes_the_nearest_centres_height():
    """The rule of `qota sample` (README "The outer half pixel"): a point between the outermost
    pixel centres and the raster's edge answers the height at the nearest point on the centres'
    lines, which is linear between two centres along the line (the triangles' outer side); off
    the raster, NaN. Expected values computed here: np.interp along the outermost rows and
    columns, the brute force inside."""
    rng = np.random.default_rng(7)
    heights = rng.uniform(0, 100, (3, 4))
    transform = (100.0, 10.0, 0.0, 500.0, 0.0, -10.0)  # 4 x 3 pixels of 10 m, top-left (100, 500)
    terrain = qota.Terrain.from_array(heights, transform)
    xs = 105 + 10 * np.arange(4)  # pixel centres
    ys = 495 - 10 * np.arange(3)
    x = rng.uniform(100, 140, 3000)  # the whole footprint, outer half pixel included
    y = rng.uniform(470, 500, 3000)
    cx, cy = np.clip(x, xs[0], xs[-1]), np.clip(y, ys[-1], ys[0])
    inx, iny = cx == x, cy == y
    want = np.full(x.shape, np.nan)
    row = np.where(y > ys[0], 0, 2)  # the outermost row a clamped y lies on
    col = np.where(x < xs[0], 0, 3)
    only_y = inx & ~iny
    want[only_y] = [np.interp(cx[i], xs, heights[row[i]]) for i in np.flatnonzero(only_y)]
    only_x = ~inx & iny
    want[only_x] = [np.interp(cy[i], ys[::-1], heights[::-1, col[i]]) for i in np.flatnonzero(only_x)]
    corner = ~inx & ~iny
    want[corner] = heights[row[corner], col[corner]]
    # Inside: the pixel centres' triangles by the raster rule, brute force.
    cols, rows = np.meshgrid(np.arange(4), np.arange(3))
    v = np.column_stack([xs[cols.ravel()], ys[rows.ravel()], heights.ravel()])
    t = []
    for r in range(2):
        for c in range(3):
            i = r * 4 + c
            t += [[i, i + 4, i + 5], [i, i + 5, i + 1]]
    inner, near = brute_force(v, np.array(t), x, y)
    want[inx & iny] = inner[inx & iny]
    check = ~(inx & iny & near)
    assert np.count_nonzero(~(inx & iny)) > 1000 and np.count_nonzero(corner) > 100
    np.testing.assert_allclose(terrain.heights(x, y)[check], want[check], rtol=0, atol=1e-9)
    # Off the raster: no terrain.
    off = terrain.heights(np.array([99.999, 140.001, 120.0, 120.0]), np.array([480.0, 480.0, 500.001, 469.999]))
    assert np.isnan(off).all()


def test_arguments_are_refused_by_name():
    # pybind11's "incompatible function arguments" before: now qota.Error (or MemoryError) naming
    # the argument.
    with pytest.raises(qota.Error, match="band must be from 1 to"):
        qota.Terrain.from_raster(DATA / "SainteHelens.dem", band=2**40)
    with pytest.raises(qota.Error, match="band must be a whole number"):
        qota.Terrain.from_raster(DATA / "SainteHelens.dem", band="1")
    with pytest.raises(qota.Error, match="azimuth must be a number"):
        qota.shadow(DATA / "SainteHelens.dem", "abc", 45)
    with pytest.raises(qota.Error, match="z_factor must be a number"):
        qota.shadow(DATA / "SainteHelens.dem", 90, 45, z_factor=[2])
    with pytest.raises(MemoryError, match="heights of shape"):
        qota.Terrain.from_array(np.broadcast_to(1.0, (1000000, 1000000)), (0, 1, 0, 0, 0, -1))


def test_one_row_or_column_is_refused():
    # One row of pixel centres spans no surface: refused, not NaN at the centres.
    for shape in ((1, 100), (100, 1), (1, 1)):
        with pytest.raises(qota.Error, match="at least 2 x 2"):
            qota.Terrain.from_array(np.full(shape, 42.0), (500000, 30, 0, 5100000, 0, -30))


def test_heights_over_a_geoid_and_lights_of_the_body():
    # SRTM heights are over EGM96: the terrain says so (assumed), and answers in the raster's own
    # heights; over the ellipsoid when asked.
    rainier = DATA / "mt_rainier_90m.tif"
    geoid = qota.Terrain.from_raster(rainier, mapping="geodetic")
    assert "EGM96 geoid" in geoid.height_ref and "assumed" in geoid.height_ref
    assert qota.Terrain.from_raster(rainier, mapping="geodetic", height_ref="ellipsoid").height_ref.startswith("ellipsoid")
    assert qota.Terrain.from_raster(rainier).height_ref is None  # a map keeps its heights
    x, y = -121.5, 46.5  # a pixel centre: its own value
    assert geoid.heights(x, y) == pytest.approx(qota.Terrain.from_raster(rainier).heights(x, y), abs=1e-6)
    with pytest.raises(qota.Error, match="egm2008|us_nga_egm08_25"):
        qota.Terrain.from_raster(rainier, mapping="geodetic", height_ref="egm2008")
    # Lights in the body's frame, as the tool takes them: the same pixels from a vector and from
    # its sub-solar point; refused where they do not apply.
    dem = DATA / "SainteHelens.dem"
    v = qota.shadow(dem, sun_vector_body=(0.3, -0.9, 0.2))
    lon, lat = np.degrees(np.arctan2(-0.9, 0.3)), np.degrees(np.arcsin(0.2 / np.linalg.norm([0.3, -0.9, 0.2])))
    np.testing.assert_array_equal(qota.shadow(dem, subsolar=(lon, lat)), v)
    assert qota.shadow(dem, sun_vector=(0.5, 0.5, 0.7), flat=True).shape == v.shape
    with pytest.raises(qota.Error, match="sun_vector_body must be 3 numbers"):
        qota.shadow(dem, sun_vector_body=(1, 2))


def test_a_lon_lat_map_gives_heights_and_polygons_but_no_mixed_normals():
    # A longitude/latitude raster in the cartesian mapping: x, y in degrees, heights in metres.
    # Its heights and polygons are right; its normals would mix the units, so hits() refuses them
    # unless normals=False.
    heights = np.arange(20.0).reshape(4, 5) * 10
    terrain = qota.Terrain.from_array(heights, (10.0, 0.1, 0, 45.0, 0, -0.1), crs="EPSG:4326")
    with pytest.raises(qota.Error, match="normals=False"):
        terrain.hits(10.2, 44.8)
    hit = terrain.hits(10.25, 44.85, normals=False)
    assert hit.normal is None and hit.polygon >= 0
    assert hit.height == terrain.heights(10.25, 44.85)
