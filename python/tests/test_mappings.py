"""Terrains in the curved mappings (spherical, geodetic, cylindrical) against a brute force written
here: the raster's triangles placed in 3D by the mapping's own formulas (a sphere, the WGS84 or
another ellipsoid, a station's cylinder), and every query line intersected with every triangle in
long double. Nothing expected comes from qota itself."""
import os
from pathlib import Path

import numpy as np
import pytest

import qota

DATA = Path(os.environ.get("QOTA_DATA_DIR", Path(__file__).resolve().parents[2] / "data"))

WGS84_A, WGS84_F = 6378137.0, 1 / 298.257223563
LD = np.longdouble


# ---- the geometry, independently ---------------------------------------------------------------

def pixel_centres(shape, transform):
    """(lon, lat) of every pixel centre, row-major, as GDAL's geotransform places them."""
    rows, cols = np.meshgrid(np.arange(shape[0]), np.arange(shape[1]), indexing="ij")
    x0, dx, rx, y0, ry, dy = transform
    return x0 + (cols + 0.5) * dx + (rows + 0.5) * rx, y0 + (cols + 0.5) * ry + (rows + 0.5) * dy


def grid_triangles(rows, cols, valid, wrap=False):
    """Two triangles a cell, split along the top-left to bottom-right diagonal, none touching an
    invalid vertex; with wrap, also the cells between the last column and the first."""
    tris = []
    for r in range(rows - 1):
        for c in range(cols if wrap else cols - 1):
            tl, tr = r * cols + c, r * cols + (c + 1) % cols
            bl, br = tl + cols, tr + cols
            for t in ([tl, bl, br], [tl, br, tr]):
                if valid[t].all():
                    tris.append(t)
    return tris


def unit_up(lon, lat):
    lon, lat = np.deg2rad(np.asarray(lon, LD)), np.deg2rad(np.asarray(lat, LD))
    return np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)], axis=-1)


def planet_mesh(heights, transform, radius):
    """A lon/lat raster as a planet: pixel centres at radius + height along (lon, lat); a raster
    spanning 360 degrees closed across the antimeridian and, where its outer rows are within a
    pixel of a pole, fanned to a pole vertex at the mean height of that row."""
    rows, cols = heights.shape
    lon, lat = pixel_centres(heights.shape, transform)
    h = heights.ravel().astype(LD)
    valid = np.isfinite(h)
    wrap = abs(cols * transform[1] - 360) < 0.5 * transform[1]
    tris = grid_triangles(rows, cols, valid, wrap)
    lon, lat = list(lon.ravel()), list(lat.ravel())
    h = list(h)
    pixel = -transform[5]
    for row, pole in ((0, 90.0), (rows - 1, -90.0)):
        centre_lat = lat[row * cols]
        if wrap and abs(pole - centre_lat) <= pixel and abs(centre_lat) < 90:
            ring = np.array(h[row * cols:(row + 1) * cols])
            lon.append(0.0), lat.append(pole), h.append(ring[np.isfinite(ring)].mean())
            for c in range(cols):
                a, b = row * cols + c, row * cols + (c + 1) % cols
                if np.isfinite(h[a]) and np.isfinite(h[b]):
                    tris.append([a, b, len(h) - 1])
    h = np.array(h, LD)
    vertices = (radius + np.where(np.isfinite(h), h, 0))[:, None] * unit_up(lon, lat)
    return vertices, np.array(tris)


def ellipsoid_point(lon, lat, h, a, f):
    """Geocentric (ECEF) x, y, z of (lon, lat, h) on the ellipsoid (a, f)."""
    e2 = LD(f) * (2 - LD(f))
    s = np.sin(np.deg2rad(np.asarray(lat, LD)))
    n = LD(a) / np.sqrt(1 - e2 * s * s)
    up = unit_up(lon, lat)
    h = np.asarray(h, LD)
    return np.stack([(n + h) * up[..., 0], (n + h) * up[..., 1], (n * (1 - e2) + h) * s], axis=-1)


def ellipsoid_mesh(heights, transform, a, f, metres=1.0):
    lon, lat = pixel_centres(heights.shape, transform)
    h = heights.ravel()
    valid = np.isfinite(h)
    tris = grid_triangles(*heights.shape, valid)
    return ellipsoid_point(lon.ravel(), lat.ravel(), np.where(valid, h, 0).astype(LD) * LD(metres), a, f), np.array(tris)


def station_mesh(heights, radius, length):
    """The raster as a station's relief: column i at angle -180 + 360 i / columns, row j at axial
    -length / 2 + length j / (rows - 1), at radius - height from the z axis; the last column
    joined to the first."""
    rows, cols = heights.shape
    j, i = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    r = (LD(radius) - heights.astype(LD)).ravel()
    angle = np.deg2rad((-180 + LD(360) * i / cols).ravel())
    axial = (-LD(length) / 2 + LD(length) * j / (rows - 1)).ravel()
    valid = np.isfinite(r)
    r = np.where(valid, r, 0)
    vertices = np.stack([r * np.cos(angle), r * np.sin(angle), axial], axis=-1)
    return vertices, np.array(grid_triangles(rows, cols, valid, wrap=True))


def crossings(origins, directions, vertices, triangles):
    """Where each line origins[i] + t directions[i] (t > 0) crosses each triangle, in long double:
    t (N, M), NaN for a miss; near (N,): the line passes within 1e-9 (relative) of some edge, where
    a neighbour or a hole may answer instead. Inside: the three edge planes through the line's
    origin agree in sign (either winding)."""
    o, d = origins.astype(LD), directions.astype(LD)
    t_all = np.full((len(o), len(triangles)), np.nan)
    near = np.zeros(len(o), bool)
    for k, tri in enumerate(triangles):
        a, b, c = (vertices[i].astype(LD) for i in tri)
        oa, ob, oc = a - o, b - o, c - o
        sides = [np.einsum("ij,ij->i", d, np.cross(p, q)) / (np.linalg.norm(p, axis=1) * np.linalg.norm(q, axis=1))
                 for p, q in ((oa, ob), (ob, oc), (oc, oa))]
        s = np.stack(sides)
        near |= np.min(np.abs(s), axis=0) < 1e-9
        inside = np.all(s > 0, axis=0) | np.all(s < 0, axis=0)
        n = np.cross(b - a, c - a)
        t = np.einsum("j,ij->i", n, oa) / (d @ n)
        hit = inside & (t > 0)
        t_all[hit, k] = t[hit]
    return t_all, near


def answers(t, z=None, up=True):
    """top, or (below, above) z, from the crossings t (N, M): "up" is larger t (a planet, an
    ellipsoid) or smaller t (a station: toward the axis). NaN where there is none."""
    sign = 1.0 if up else -1.0
    s = sign * t  # larger s is up
    none = lambda v: np.where(np.isinf(v), np.nan, sign * v)  # noqa: E731
    if z is None:
        return none(np.max(np.where(np.isnan(s), -np.inf, s), axis=1))
    zs = sign * np.asarray(z, float)[:, None]
    below = np.max(np.where(s <= zs, s, -np.inf), axis=1)  # (NaN compares false: a miss)
    above = np.min(np.where(s >= zs, s, np.inf), axis=1)
    return none(below), none(above)


def assert_matches(got, want, near, atol=1e-6):
    """Equal to atol away from edges (a line through an edge may meet either neighbour); the
    same cells without terrain."""
    clear = ~near
    assert np.count_nonzero(clear) > 0.9 * clear.size
    np.testing.assert_array_equal(np.isnan(got[clear]), np.isnan(want[clear]))
    ok = clear & ~np.isnan(want)
    np.testing.assert_allclose(got[ok], want[ok], rtol=0, atol=atol)


# ---- spherical ------------------------------------------------------------------------------

def global_raster(rng, nodata=-9999.0):
    """A 10-degree global lon/lat raster (36 x 18 pixels, centres 85 N to 85 S), with nodata pixels,
    one of them in the top row (the pole's height is the mean of the others)."""
    heights = rng.uniform(-4000, 6000, (18, 36))
    heights[7, 11] = heights[12, 30] = heights[0, 5] = nodata
    return heights, (-180.0, 10.0, 0.0, 90.0, 0.0, -10.0)


def test_spherical_planet_matches_rays_from_the_centre():
    rng = np.random.default_rng(10)
    heights, transform = global_raster(rng)
    radius = 1737400.0  # the Moon
    terrain = qota.Terrain.from_array(heights, transform, nodata=-9999, mapping="spherical", radius=radius)
    assert terrain.mapping == "spherical"
    v, t = planet_mesh(np.where(heights == -9999, np.nan, heights), transform, radius)
    n = 3000
    lon = rng.uniform(-180, 180, n)
    lat = np.rad2deg(np.arcsin(rng.uniform(-1, 1, n)))  # uniform on the sphere: the caps too
    hits, near = crossings(np.zeros((n, 3)), unit_up(lon, lat), v, t)
    want = answers(hits)
    got = terrain.heights(lon, lat)
    assert_matches(got, want, near)
    assert np.count_nonzero(np.isnan(want)) > 10  # the holes were asked about
    z = radius + rng.uniform(-5000, 7000, n)
    want_below, want_above = answers(hits, z)
    assert_matches(terrain.below(lon, lat, z), want_below, near)
    assert_matches(terrain.above(lon, lat, z), want_above, near)
    lo, hi = terrain.bracket(lon, lat, z)
    np.testing.assert_array_equal(lo, terrain.below(lon, lat, z))
    np.testing.assert_array_equal(hi, terrain.above(lon, lat, z))


def test_spherical_poles_seam_and_default_radius():
    rng = np.random.default_rng(11)
    heights, transform = global_raster(rng)
    terrain = qota.Terrain.from_array(heights, transform, nodata=-9999, crs="EPSG:4326", mapping="spherical")
    # No radius: the mean radius (2a + b) / 3 of the CRS's ellipsoid (WGS84).
    radius = (2 * WGS84_A + WGS84_A * (1 - WGS84_F)) / 3
    valid = lambda row: row[row != -9999]  # noqa: E731
    # At a pole every longitude names one ray: the pole vertex, at the mean height of its row.
    np.testing.assert_allclose(terrain.heights([0, 77, -180], 90.0), radius + valid(heights[0]).mean(), rtol=0, atol=1e-6)
    np.testing.assert_allclose(terrain.heights(33.0, -90.0), radius + valid(heights[-1]).mean(), rtol=0, atol=1e-6)
    # The antimeridian: -180 and 180 are one meridian, and longitudes wrap.
    lat = rng.uniform(-80, 80, 200)
    np.testing.assert_array_equal(terrain.heights(180.0, lat), terrain.heights(-180.0, lat))
    lon = rng.uniform(-180, 180, 200)
    np.testing.assert_allclose(terrain.heights(lon + 360, lat), terrain.heights(lon, lat), rtol=0, atol=1e-6)
    v, t = planet_mesh(np.where(heights == -9999, np.nan, heights), transform, radius)
    seam = np.array([180.0, -180.0, 179.999, -179.999])
    seam_lat = np.array([3.3, -41.0, 60.2, 12.0])
    hits, near = crossings(np.zeros((4, 3)), unit_up(seam, seam_lat), v, t)
    assert_matches(terrain.heights(seam, seam_lat), answers(hits), near)


# ---- geodetic -------------------------------------------------------------------------------

def local_raster(rng, nodata=-32768.0):
    """0.01-degree pixels near Mt. Rainier, heights 200-4400, a nodata pixel."""
    heights = rng.uniform(200, 4400, (12, 15))
    heights[5, 6] = nodata
    return heights, (-122.0, 0.01, 0.0, 47.0, 0.0, -0.01)


def normal_lines(lon, lat, a, f):
    """The ellipsoid normal at (lon, lat): the surface point and the unit normal (up)."""
    return ellipsoid_point(lon, lat, np.zeros_like(lon), a, f), unit_up(lon, lat)


@pytest.mark.parametrize("crs, a, f", [
    ("EPSG:4326", WGS84_A, WGS84_F),
    (None, WGS84_A, WGS84_F),  # no CRS: WGS84
    ("+proj=longlat +a=3396190 +rf=169.894447223612 +no_defs", 3396190.0, 1 / 169.894447223612),  # Mars
])
def test_geodetic_heights_along_the_ellipsoid_normal(crs, a, f):
    rng = np.random.default_rng(12)
    heights, transform = local_raster(rng)
    terrain = qota.Terrain.from_array(heights, transform, nodata=-32768, crs=crs, mapping="geodetic",
                                      height_ref="ellipsoid")  # (the geoid: test_geoid.py)
    assert terrain.mapping == "geodetic" and terrain.height_ref.startswith("ellipsoid")
    v, t = ellipsoid_mesh(np.where(heights == -32768, np.nan, heights), transform, a, f)
    n = 2000
    lon, lat = rng.uniform(-121.995, -121.855, n), rng.uniform(46.885, 46.995, n)
    o, d = normal_lines(lon, lat, a, f)
    hits, near = crossings(o, d, v, t)
    assert_matches(terrain.heights(lon, lat), answers(hits), near)
    z = rng.uniform(0, 5000, n)
    want_below, want_above = answers(hits, z)
    assert_matches(terrain.below(lon, lat, z), want_below, near)
    assert_matches(terrain.above(lon, lat, z), want_above, near)


def test_geodetic_heights_in_the_rasters_unit():
    # A raster in feet: its vertices stand at height * 0.3048 m above the ellipsoid, and queries
    # and answers are in feet (as qota sample reads and prints them).
    rng = np.random.default_rng(13)
    heights, transform = local_raster(rng)
    feet = qota.Terrain.from_array(heights, transform, nodata=-32768, crs="EPSG:4326", unit="ft", mapping="geodetic",
                                   height_ref="ellipsoid")
    v, t = ellipsoid_mesh(np.where(heights == -32768, np.nan, heights), transform, WGS84_A, WGS84_F, metres=0.3048)
    n = 1000
    lon, lat = rng.uniform(-121.995, -121.855, n), rng.uniform(46.885, 46.995, n)
    o, d = normal_lines(lon, lat, WGS84_A, WGS84_F)
    hits, near = crossings(o, d, v, t)
    assert_matches(feet.heights(lon, lat), answers(hits) / 0.3048, near)
    z = rng.uniform(0, 15000, n)
    want_below, _ = answers(hits, z * 0.3048)
    assert_matches(feet.below(lon, lat, z), want_below / 0.3048, near)


# ---- cylindrical ----------------------------------------------------------------------------

@pytest.mark.parametrize("radius, length", [(None, None), (800.0, 3000.0)])
def test_cylindrical_station_distance_from_the_axis(radius, length):
    rng = np.random.default_rng(14)
    heights = rng.uniform(0, 60, (7, 24))
    heights[3, 10] = np.nan  # a window in the hull
    terrain = qota.Terrain.from_array(heights, (0, 1, 0, 0, 0, -1), mapping="cylindrical", radius=radius,
                                      length=length)
    assert terrain.mapping == "cylindrical"
    r, half = (radius or 250.0), (length or 1000.0) / 2
    v, t = station_mesh(heights, r, 2 * half)
    n = 3000
    angle, axial = rng.uniform(-180, 180, n), rng.uniform(-1.05 * half, 1.05 * half, n)
    origins = np.column_stack([np.zeros(n), np.zeros(n), axial])
    outward = np.column_stack([np.cos(np.deg2rad(angle)), np.sin(np.deg2rad(angle)), np.zeros(n)])
    hits, near = crossings(origins, outward, v, t)
    # Up is toward the axis: the top surface is the nearest to it, "below" is farther out.
    assert_matches(terrain.heights(angle, axial), answers(hits, up=False), near)
    assert np.count_nonzero(np.abs(axial) > half) > 50  # past the ends too
    z = r - rng.uniform(-10, 70, n)
    want_below, want_above = answers(hits, z, up=False)
    got_below, got_above = terrain.bracket(angle, axial, z)
    assert_matches(got_below, want_below, near)
    assert_matches(got_above, want_above, near)


# ---- every mapping: the same calls and policies ---------------------------------------------

def terrains():
    rng = np.random.default_rng(15)
    g, gt = global_raster(rng)
    h, ht = local_raster(rng)
    return {
        "cartesian": qota.Terrain.from_array(h, ht, nodata=-32768),
        "spherical": qota.Terrain.from_array(g, gt, nodata=-9999, mapping="spherical"),
        "geodetic": qota.Terrain.from_array(h, ht, nodata=-32768, crs="EPSG:4326", mapping="geodetic"),
        "cylindrical": qota.Terrain.from_array(rng.uniform(0, 50, (6, 20)), (0, 1, 0, 0, 0, -1), mapping="cylindrical"),
    }


def test_every_mapping_answers_every_call(tmp_path):
    rng = np.random.default_rng(16)
    for name, terrain in terrains().items():
        assert terrain.mapping == name and name in qota.MAPPINGS and name in repr(terrain)
        if name in ("cartesian", "geodetic"):
            x, y = rng.uniform(-121.99, -121.86, 500), rng.uniform(46.89, 46.99, 500)
        elif name == "spherical":
            x, y = rng.uniform(-180, 180, 500), rng.uniform(-90, 90, 500)
        else:
            x, y = rng.uniform(-180, 180, 500), rng.uniform(-400, 400, 500)
        h = terrain.heights(x.reshape(20, 25), y.reshape(20, 25))
        assert h.shape == (20, 25) and np.count_nonzero(~np.isnan(h)) > 400
        h = h.ravel()
        # The top surface is below (and above) itself.
        np.testing.assert_array_equal(terrain.below(x, y, h), h)
        np.testing.assert_array_equal(terrain.above(x, y, h), h)
        # Polygons and normals: unit normals facing up (away from the centre; toward the axis).
        top, poly, normal = terrain.hits(x, y)
        np.testing.assert_array_equal(top, h)
        hit = ~np.isnan(h)
        assert np.all(poly[hit] >= 0) and np.all(poly[~hit] == -1)
        np.testing.assert_allclose(np.linalg.norm(normal[hit], axis=1), 1, atol=1e-12)
        if name == "spherical":
            assert np.all(np.einsum("ij,ij->i", normal[hit], unit_up(x[hit], y[hit]).astype(float)) > 0.5)
        if name == "cylindrical":
            out = np.column_stack([np.cos(np.deg2rad(x)), np.sin(np.deg2rad(x)), np.zeros_like(x)])
            assert np.all(np.einsum("ij,ij->i", normal[hit], out[hit]) < -0.5)
        k = int(np.flatnonzero(hit)[0])
        layers = terrain.all(x[k], y[k])
        assert layers and layers[0][0] == pytest.approx(h[k], abs=1e-6) and layers[0][1] == poly[k]
        s = terrain.stats()
        assert s["triangles"] > 0 and s["memory_bytes"] > 0
        # A tree file keeps the mapping (and answers alike).
        terrain.save(tmp_path / f"{name}.qota")
        back = qota.Terrain.load(tmp_path / f"{name}.qota")
        assert back.mapping == name
        np.testing.assert_array_equal(back.heights(x, y), h)


def test_a_geodetic_tree_keeps_its_unit(tmp_path):
    rng = np.random.default_rng(17)
    heights, transform = local_raster(rng)
    feet = qota.Terrain.from_array(heights, transform, nodata=-32768, crs="EPSG:4326", unit="ft", mapping="geodetic",
                                   height_ref="ellipsoid")
    feet.save(tmp_path / "feet.qota")
    back = qota.Terrain.load(tmp_path / "feet.qota")
    x, y = rng.uniform(-121.99, -121.86, 300), rng.uniform(46.89, 46.99, 300)
    np.testing.assert_array_equal(back.heights(x, y), feet.heights(x, y))
    np.testing.assert_array_equal(back.below(x, y, 9000.0), feet.below(x, y, 9000.0))


def test_points_without_a_line_are_nan():
    # The policy: a point whose coordinates name no line (a latitude outside [-90, 90], NaN or
    # infinite) is NaN like a point off the terrain; the batch does not raise for it.
    t = terrains()
    for name in ("spherical", "geodetic"):
        h = t[name].heights([10.0, 10.0, 10.0, np.nan, np.inf], [90.5, -91.0, np.nan, 45.0, 45.0])
        assert np.isnan(h).all()
        assert np.isnan(t[name].below([10.0], [95.0], [7e6])).all()
        assert np.isnan(t[name].above([10.0], [95.0], [0.0])).all()
        h, p, _ = t[name].hits(10.0, 91.0)
        assert np.isnan(h) and p == -1
        assert t[name].all(10.0, 91.0) == []
    assert np.isnan(t["cylindrical"].heights([np.nan, 10.0], [0.0, np.inf])).all()
    assert not np.isnan(t["spherical"].heights(10.0, 89.9999))


def test_mapping_options_are_checked(tmp_path):
    data = DATA
    heights, transform = local_raster(np.random.default_rng(18))
    with pytest.raises(qota.Error, match="mapping 'polar' is not one of"):
        qota.Terrain.from_array(heights, transform, mapping="polar")
    with pytest.raises(qota.Error, match="radius applies"):
        qota.Terrain.from_array(heights, transform, mapping="geodetic", radius=6e6)
    with pytest.raises(qota.Error, match="length applies"):
        qota.Terrain.from_array(heights, transform, mapping="spherical", length=10)
    with pytest.raises(qota.Error, match="radius must be a positive"):
        qota.Terrain.from_array(heights, transform, mapping="spherical", radius=-1)
    with pytest.raises(qota.Error, match="radius must be a number"):
        qota.Terrain.from_array(heights, transform, mapping="spherical", radius="big")
    with pytest.raises(qota.Error, match="reaches the axis"):
        qota.Terrain.from_array(heights, (0, 1, 0, 0, 0, -1), mapping="cylindrical", radius=100)
    # A projected raster (UTM) has no longitudes and latitudes.
    with pytest.raises(qota.Error, match="longitude/latitude"):
        qota.Terrain.from_raster(data / "SainteHelens.dem", mapping="geodetic")
    with pytest.raises(qota.Error, match="longitude/latitude"):
        qota.Terrain.from_raster(data / "SainteHelens.dem", mapping="spherical")
    with pytest.raises(qota.Error, match="mapping 'xyz'"):
        qota.Terrain.from_raster(data / "SainteHelens.dem", mapping="xyz")
    terrains()["cylindrical"].save(tmp_path / "t.qota")
    with pytest.raises(qota.Error, match="a tree file, not a raster"):
        qota.Terrain.from_raster(tmp_path / "t.qota", mapping="cylindrical")
    with pytest.raises(qota.Error, match="ECEF vertices on the Earth"):
        qota.Terrain.from_mesh([[0, 0, 1], [1, 0, 1], [0, 1, 1]], [[0, 1, 2]], mapping="enu")
    with pytest.raises(qota.Error, match="origin applies to the enu mapping"):
        qota.Terrain.from_mesh([[0, 0, 1], [1, 0, 1], [0, 1, 1]], [[0, 1, 2]], origin=(0, 0))
    with pytest.raises(qota.Error, match="not a coordinate reference system"):
        qota.Terrain.from_array(heights, transform, crs="EPSG:999999", mapping="geodetic")


def test_spherical_mesh_in_world_coordinates():
    # from_mesh in the spherical mapping: an octahedron about the origin; the ray from the centre
    # meets a face where x/|x| + y/|y| + z/|z| = 1 over the vertex radius.
    r = 1000.0
    v = r * np.array([[1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
    faces = [[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4], [1, 0, 5], [2, 1, 5], [3, 2, 5], [0, 3, 5]]
    terrain = qota.Terrain.from_mesh(v, faces, mapping="spherical")
    rng = np.random.default_rng(19)
    lon, lat = rng.uniform(-180, 180, 1000), rng.uniform(-90, 90, 1000)
    u = unit_up(lon, lat).astype(float)
    np.testing.assert_allclose(terrain.heights(lon, lat), r / np.abs(u).sum(axis=1), rtol=1e-12)


# ---- arrays that are not what the C++ side takes --------------------------------------------

def test_bad_arrays_are_converted_or_refused():
    terrain = terrains()["spherical"]
    rng = np.random.default_rng(20)
    lon, lat = rng.uniform(-180, 180, (40, 30)), rng.uniform(-80, 80, (40, 30))
    want = terrain.heights(lon, lat)
    # Converted: integers, float32, another byte order, strided views, Fortran order, lists.
    np.testing.assert_array_equal(terrain.heights(lon.astype(">f8"), lat), want)
    np.testing.assert_array_equal(terrain.heights(np.asfortranarray(lon), lat), want)
    np.testing.assert_array_equal(terrain.heights(lon[::2, ::3], lat[::2, ::3]), want[::2, ::3])
    np.testing.assert_array_equal(terrain.heights(lon.T, lat.T), want.T)
    np.testing.assert_array_equal(terrain.heights(lon.tolist(), lat.tolist()), want)
    ints = terrain.heights(np.arange(-170, 170, 10, dtype=np.int16), np.int64(20))
    np.testing.assert_array_equal(ints, terrain.heights(np.arange(-170, 170, 10, dtype=float), 20.0))
    assert terrain.heights(np.float32(10), 20).shape == ()
    # Refused, naming the argument: complex numbers (numpy would drop the imaginary part),
    # strings; shapes that do not broadcast.
    with pytest.raises(qota.Error, match="x must be real numbers"):
        terrain.heights(lon + 1j, lat)
    with pytest.raises(qota.Error, match="z must be real numbers"):
        terrain.below(lon, lat, "high")
    with pytest.raises(qota.Error, match="do not broadcast"):
        terrain.heights(np.zeros(3), np.zeros(4))
    with pytest.raises(qota.Error, match="do not broadcast"):
        terrain.hits(np.zeros(3), np.zeros(3), np.zeros(2), side="below")
    # Heights: 2-D only; a masked array's masked pixels are holes.
    with pytest.raises(qota.Error, match="2-D"):
        qota.Terrain.from_array(np.zeros((2, 3, 4)), (0, 1, 0, 0, 0, -1))
    with pytest.raises(qota.Error, match="heights must be real numbers"):
        qota.Terrain.from_array(np.zeros((3, 3), complex), (0, 1, 0, 0, 0, -1))
    plane = np.ma.masked_array(np.full((5, 5), 7.0), mask=np.zeros((5, 5), bool))
    plane.mask[2, 2] = True
    flat = qota.Terrain.from_array(plane, (0, 1, 0, 5, 0, -1))
    assert np.isnan(flat.heights(2.5, 2.5)) and flat.heights(1.0, 4.0) == 7.0


def test_curved_batches_run_while_other_threads_run():
    # The GIL is released during a batch, in every mapping: two threads' batches give the same
    # answers as one.
    import threading

    terrain = terrains()["geodetic"]
    rng = np.random.default_rng(21)
    x, y, z = rng.uniform(-122, -121.85, 200000), rng.uniform(46.88, 47, 200000), rng.uniform(0, 5000, 200000)
    want = [terrain.heights(x, y), terrain.below(x, y, z), terrain.above(x, y, z)]
    got = [None, None]

    def run(i):
        got[i] = [terrain.heights(x, y), terrain.below(x, y, z), terrain.above(x, y, z)]

    threads = [threading.Thread(target=run, args=(i,)) for i in range(2)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    for g in got:
        for a, b in zip(g, want):
            np.testing.assert_array_equal(a, b)


def test_enu_is_reached_as_the_tool_reaches_it(tmp_path):
    # A DEM on its ellipsoid seen east-north-up at an origin: Terrain.from_raster(mapping="enu")
    # answers as `qota sample --mapping enu` does (the tool's output, read here), and a tree file
    # keeps it. (Each answer against GeographicLib's LocalCartesian: EnuTool.* in the C++ suite.)
    import subprocess
    from test_interop import RAINIER
    origin = (46.85, -121.76, 1000.0)
    terrain = qota.Terrain.from_raster(RAINIER, mapping="enu", origin=origin)
    assert terrain.mapping == "enu"
    rng = np.random.default_rng(21)
    east, north = rng.uniform(-20000, 20000, 200), rng.uniform(-20000, 20000, 200)
    got = terrain.heights(east, north)
    assert np.count_nonzero(~np.isnan(got)) > 150
    tool = os.environ.get("QOTA_TOOL") or str(Path(__file__).resolve().parents[2] / "build" / "tools" / "qota")
    if os.path.exists(tool):
        text = "".join(f"{e!r} {n!r}\n" for e, n in zip(east, north))
        run = subprocess.run([tool, "sample", str(RAINIER), "--mapping", "enu", "--origin", "46.85,-121.76,1000"],
                             input=text, capture_output=True, text=True)
        want = np.array([np.nan if v == "none" else float(v) for v in run.stdout.split()])
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-9)
    terrain.save(tmp_path / "enu.qota")
    np.testing.assert_array_equal(qota.Terrain.load(tmp_path / "enu.qota").heights(east, north), got)
    with pytest.raises(qota.Error, match="origin applies to the enu mapping"):
        qota.Terrain.from_raster(RAINIER, origin=origin)


def test_enu_mesh_is_seen_from_its_origin():
    # ECEF vertices of a square 100 m above the origin's tangent plane (built here with the
    # textbook east-north-up rotation): from_mesh(mapping="enu") answers 100 over it, nothing
    # outside it.
    a, f = 6378137.0, 1 / 298.257223563
    lat, lon = np.radians(46.85), np.radians(-121.76)
    e2 = f * (2 - f)
    n = a / np.sqrt(1 - e2 * np.sin(lat) ** 2)
    centre = np.array([n * np.cos(lat) * np.cos(lon), n * np.cos(lat) * np.sin(lon), n * (1 - e2) * np.sin(lat)])
    east = np.array([-np.sin(lon), np.cos(lon), 0])
    north = np.array([-np.sin(lat) * np.cos(lon), -np.sin(lat) * np.sin(lon), np.cos(lat)])
    up = np.array([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)])
    square = [(-500, -500), (500, -500), (500, 500), (-500, 500)]
    vertices = [centre + e * east + nn * north + 100 * up for e, nn in square]
    terrain = qota.Terrain.from_mesh(vertices, [[0, 1, 2], [0, 2, 3]], mapping="enu", origin=(46.85, -121.76))
    got = terrain.heights([0, 120, -480, 600], [0, -300, 470, 0])
    np.testing.assert_allclose(got[:3], 100, atol=1e-6)
    assert np.isnan(got[3])


# A point in each mapping's source coordinates over the registry raster below (see
# tests/test_registry.cpp): a mapping added to the registry without one here fails.
REGISTRY_POINTS = {"cartesian": (10.2, 44.85), "spherical": (10.2, 44.85), "cylindrical": (10, 0),
                   "geodetic": (10.2, 44.85), "enu": (120, -80)}


def test_every_mapping_of_the_registry_is_reached(tmp_path):
    # qota.MAPPINGS is the library's registry; each is built from a raster, answers as the tool
    # answers, and survives a tree file; the stub's Literal lists the same names.
    import ast
    import subprocess
    stub = ast.parse((Path(qota.__file__).parent / "__init__.pyi").read_text())
    literal = next(node.value for node in ast.walk(stub)
                   if isinstance(node, ast.Assign) and getattr(node.targets[0], "id", "") == "_Mapping")
    assert tuple(e.value for e in literal.slice.elts) == qota.MAPPINGS
    rows, cols = np.mgrid[0:30, 0:40]
    heights = 60 + 20 * np.sin(0.3 * cols) + 15 * np.cos(0.2 * rows) + cols
    path = tmp_path / "registry.tif"
    rasterio = pytest.importorskip("rasterio")
    with rasterio.open(path, "w", driver="GTiff", width=40, height=30, count=1, dtype="float64", crs="EPSG:4326",
                       transform=rasterio.Affine(0.01, 0, 10.0, 0, -0.01, 45.0)) as out:
        out.write(heights, 1)
    tool = os.environ.get("QOTA_TOOL") or str(Path(__file__).resolve().parents[2] / "build" / "tools" / "qota")
    for name in qota.MAPPINGS:
        assert name in REGISTRY_POINTS, f"mapping {name} has no test point"
        x, y = REGISTRY_POINTS[name]
        terrain = qota.Terrain.from_raster(path, mapping=name)
        assert terrain.mapping == name
        got = terrain.heights([x], [y])[0]
        assert np.isfinite(got)
        if os.path.exists(tool):
            run = subprocess.run([tool, "sample", str(path), "--mapping", name], input=f"{x!r} {y!r}\n",
                                 capture_output=True, text=True)
            assert run.returncode == 0, run.stderr
            assert float(run.stdout) == pytest.approx(got, rel=1e-12, abs=1e-9)
        terrain.save(tmp_path / f"{name}.qota")
        again = qota.Terrain.load(tmp_path / f"{name}.qota")
        assert again.mapping == name
        assert again.heights([x], [y])[0] == got
