"""qota: terrain heights under points, from rasters, numpy arrays and meshes.

The Quick Oriented Terrain Algorithm's quadtree core, for numpy: every call takes arrays of any
shape (broadcast together), answers in C++ on every core with the GIL released, and gives NaN
where there is no terrain (a hole, nodata, outside the data, a latitude outside [-90, 90]).

    >>> import qota
    >>> t = qota.Terrain.from_raster("data/mt_rainier_90m.tif")
    >>> t.heights([-121.7603], [46.8529])          # x, y in the raster's CRS
    array([4367.4...])

Terrains come in the mappings of qota.MAPPINGS (the `qota sample --mapping` ones): "cartesian" (a
map: x, y in the CRS, heights along -z), "spherical" (a lon/lat raster closed into a planet: lon,
lat, and the radius), "cylindrical" (the relief inside a rotating station: angle, axial, and the
distance from the axis), "geodetic" (a lon/lat raster on its ellipsoid: lon, lat, and the height
along the normal) and "enu" (that ellipsoid seen east-north-up at an origin: east, north, up).
rasterio datasets and xarray DataArrays (with rioxarray) are sources too.
"""
from __future__ import annotations

import contextlib as _contextlib
import errno as _errno
import os as _os
import re as _re
import tempfile as _tempfile
import typing as _typing
import warnings as _warnings

import numpy as _np

from . import _interop
from . import _qota
from ._qota import Error, __version__

__all__ = ["Terrain", "Hits", "Error", "__version__", "sample", "shadow", "viewshed", "sun_position", "MAPPINGS",
           "RESAMPLINGS"]

#: How qota.sample finds a raster's height at a point (`qota sample -r`): "triangle" (the exact
#: surface every qota tool sees), or GDAL's rules "nearest", "bilinear", "cubic".
RESAMPLINGS: tuple = ("triangle", "nearest", "bilinear", "cubic")

#: Heights beyond this (metres) are not terrain: a raster's, an observer's, a target's (a million
#: kilometres, past the Moon; the library holds every height to it).
MAX_HEIGHT: float = 1e9

#: The mappings a terrain can be built in (Terrain.mapping is one of these): the library's mapping
#: registry, as the tools' --mapping takes them.
MAPPINGS: tuple = _qota.MAPPINGS


def _local_file(path):
    """A local path that is not there is FileNotFoundError (an OSError), as Python's own open()
    gives; GDAL's virtual paths (/vsicurl/...) and connection strings (NAME:...) go to GDAL."""
    try:
        text = _os.fspath(path)
    except TypeError:
        raise Error(f"expected a path (str or os.PathLike), a rasterio dataset or an xarray.DataArray, "
                    f"got {type(path).__name__}") from None
    if not text.startswith("/vsi") and ":" not in text and not _os.path.exists(text):
        raise FileNotFoundError(_errno.ENOENT, "no such file", text)
    return text


def _height(value, name):
    """A height above the surface, in metres from 0 to MAX_HEIGHT (no terrain reaches beyond it)."""
    value = _number(value, name)
    if not 0 <= value <= MAX_HEIGHT:
        raise Error(f"{name} must be a number of metres from 0 to 1e9 (beyond any terrain), got {value!r}")
    return value


def _mapping(mapping) -> str:
    if mapping not in MAPPINGS:
        raise Error(f"mapping {mapping!r} is not one of {', '.join(MAPPINGS)}")
    return mapping


def _number_or_none(value, name):
    """An option (radius, length) as a float, or None for the default; what is not a number is
    refused here, naming the option (the C++ side checks that it is positive and applies)."""
    if value is None:
        return None
    try:
        return float(value)
    except (TypeError, ValueError):
        raise Error(f"{name} must be a number, got {value!r}") from None


def _whole(value, name, lo=1, hi=2**31 - 1):
    """A whole-number argument (band, threads, ...) in [lo, hi], or qota.Error naming it."""
    if isinstance(value, bool) or not isinstance(value, (int, _np.integer)):
        if isinstance(value, (float, _np.floating)) and float(value).is_integer():
            value = int(value)
        else:
            raise Error(f"{name} must be a whole number, got {value!r}")
    if not lo <= int(value) <= hi:
        raise Error(f"{name} must be from {lo} to {hi}, got {value}")
    return int(value)


def _number(value, name):
    """A real-number argument (azimuth, z_factor, ...) as a float, or qota.Error naming it."""
    if isinstance(value, (bool, str, bytes)):
        raise Error(f"{name} must be a number, got {value!r}")
    try:
        return float(value)
    except (TypeError, ValueError):
        raise Error(f"{name} must be a number, got {value!r}") from None


def _origin(origin):
    """origin=(lat, lon[, h]) as the three numbers the C++ side takes, or None."""
    if origin is None:
        return None
    try:
        values = [float(v) for v in origin]
    except (TypeError, ValueError):
        raise Error(f"origin must be (lat, lon[, h]) in degrees and metres, got {origin!r}") from None
    if len(values) not in (2, 3):
        raise Error(f"origin must be (lat, lon[, h]) in degrees and metres, got {origin!r}")
    return values + [0.0] * (3 - len(values))


def _coords(value, name):
    """A query coordinate as a float64 array: any real numbers (ints, floats, their arrays, any
    byte order or memory layout); complex numbers, strings and the like are refused, naming the
    argument, rather than cast (numpy would drop an imaginary part, or fail with less to say)."""
    a = _np.asarray(value)
    if a.dtype.kind in "iuf":
        return a.astype(_np.float64, copy=False)
    if a.dtype.kind == "O":
        try:
            return a.astype(_np.float64)
        except (TypeError, ValueError):
            pass
    raise Error(f"{name} must be real numbers, got an array of {a.dtype}")


def _broadcast(**arrays):
    """The arrays broadcast together (qota.Error naming their shapes when they do not)."""
    values = [_coords(v, k) for k, v in arrays.items()]
    try:
        return _np.broadcast_arrays(*values)
    except ValueError:
        shapes = ", ".join(f"{k} {v.shape}" for k, v in zip(arrays, values))
        raise Error(f"the coordinates do not broadcast together: {shapes}") from None


def _flat(a):
    """A broadcast array as the flat, contiguous float64 the C++ side takes (a copy only where the
    broadcast made it a view with zero strides)."""
    return _np.ascontiguousarray(a).ravel()


def _heights_array(heights):
    """A 2-D height grid as contiguous float64: masked pixels (numpy.ma) become NaN, which are
    holes. One too large for memory is a MemoryError naming it (a broadcast view is made whole
    here)."""
    if isinstance(heights, _np.ma.MaskedArray):
        heights = heights.astype(_np.float64).filled(_np.nan)
    a = _coords(heights, "heights")
    try:
        return _np.ascontiguousarray(a)
    except MemoryError as e:
        raise MemoryError(f"heights of shape {a.shape}: {e}") from None


class Hits(_typing.NamedTuple):
    """What Terrain.hits returns for every point: one type whatever is asked."""
    height: _np.ndarray  # float64, NaN where no terrain
    polygon: _np.ndarray  # int64 polygon ids, -1 where none
    normal: "_np.ndarray | None"  # float64 unit normals, shape + (3,), NaN where none; None if not asked


class Terrain:
    """A terrain: the surfaces along the lines of a mapping (verticals on a map; radii of a planet;
    ellipsoid normals; rays out from a station's axis).

    Build one with from_raster (a file, a rasterio dataset or a DataArray), from_array, from_xarray
    or from_mesh, or load a tree file (save, `qota build`). Queries take the mapping's coordinates:

    ============  =====================  ======================================================
    mapping       x, y                   heights (and z)
    ============  =====================  ======================================================
    cartesian     x, y in the CRS        the source's z, in its own unit
    spherical     lon, lat (degrees)     the surface's radius, metres from the centre
    geodetic      lon, lat (degrees)     height along the ellipsoid normal, the raster's unit
    cylindrical   angle (deg), axial     distance from the axis, metres ("below": farther out)
    ============  =====================  ======================================================

    "Below" is along the mapping's down (toward the centre; away from a station's axis), "above"
    against it, and heights() answers the topmost surface. A point with no terrain on its line
    is NaN; so is a point that has no line (a latitude outside [-90, 90], a coordinate that is NaN
    or infinite): the batch never raises for one point's values.
    """

    def __init__(self, impl: _qota._Terrain):
        self._t = impl

    @classmethod
    def from_raster(cls, path, band: int = 1, mapping: str = "cartesian", radius=None, length=None, *,
                    height_ref=None, origin=None) -> "Terrain":
        """A raster as a terrain in a mapping, as `qota sample --mapping --radius --length` reads it.

        path: a GDAL raster (GeoTIFF, VRT, ...; a path or GDAL's /vsi... name), an open rasterio
            dataset (a local file opened read-only is read from that file, any other, e.g. a
            MemoryFile, through rasterio: its band, transform, nodata, CRS and unit), or an
            xarray.DataArray with rioxarray's accessor (as from_xarray).
        band: 1-based band (for a DataArray: the position along its third dimension).
        mapping: "cartesian": pixel centres joined into two triangles a cell, nodata pixels holes,
            x and y in the raster's CRS (degrees for a lon/lat raster); "spherical": a lon/lat
            raster at radius + height along each (lon, lat) (a raster spanning 360 degrees is
            closed across the antimeridian and at the poles); "geodetic": a lon/lat raster at its
            heights above its CRS's ellipsoid (WGS84 without one); "cylindrical": the raster as
            the relief of a station around the z axis, columns the angle (-180 + 360 col / width),
            rows the axial position (-length / 2 to length / 2), hills rising toward the axis.
        radius: spherical: the planet's reference radius in metres (default: the CRS's sphere,
            or its ellipsoid's mean radius, 6371008.8 for WGS84); cylindrical: the station's
            radius (default 250). Refused for the other mappings.
        length: cylindrical: the station's length (default 1000). Refused for the others.
        height_ref: geodetic: what the raster's heights are over ("ellipsoid", "egm96", "egm2008",
            "crs", or a geoid grid's path; default: the raster's vertical CRS, else the EGM96 geoid
            on the Earth and the ellipsoid elsewhere). The surface is placed over the ellipsoid
            with the geoid's undulation; heights are read and answered in the raster's own
            reference. The choice is the terrain's height_ref. Refused for the other mappings.
        origin: enu: the east-north-up frame's origin (lat, lon[, h]): the raster is placed on its
            ellipsoid as "geodetic" places it and seen from there; x, y are east, north and
            heights up, in metres. Default: the raster's centre at height 0.
        """
        mapping = _mapping(mapping)
        if height_ref is not None and not isinstance(height_ref, (str, _os.PathLike)):
            raise Error(f"height_ref must be a text or a path, got {height_ref!r}")
        if _interop.is_dataarray(path):
            return cls.from_xarray(path, band=band, mapping=mapping, radius=radius, length=length, height_ref=height_ref,
                                   origin=origin)
        if _interop.is_xarray_dataset(path):
            raise Error("an xarray.Dataset: give one of its variables (a DataArray), e.g. ds['elevation']")
        if _interop.is_rasterio_dataset(path):
            local = _interop.local_file_of(path)
            if local is None:
                return cls._from_grid(_interop.rasterio_grid(path, _whole(band, "band")), mapping, radius, length,
                                      height_ref, origin)
            path = local
        return cls(_qota._Terrain.from_raster(_local_file(path), _whole(band, "band"), mapping,
                                              _number_or_none(radius, "radius"), _number_or_none(length, "length"),
                                              "" if height_ref is None else _os.fspath(height_ref), _origin(origin)))

    @classmethod
    def from_xarray(cls, da, band: int = 1, mapping: str = "cartesian", radius=None, length=None, *,
                    height_ref=None, origin=None) -> "Terrain":
        """An xarray.DataArray with rioxarray's `rio` accessor (rioxarray.open_rasterio, or any
        array with x/y coordinates and a CRS written by rio.write_crs), as from_raster reads the
        same raster: its values, rio.transform(), rio.nodata (NaN pixels are holes too), rio.crs
        and the `units` attribute (the vertical unit). A 2-D (y, x) array is the band; a 3-D one
        gives band `band` (1-based) of its third dimension. mapping, radius, length and height_ref
        as for from_raster. Needs rioxarray (imported here, on first use)."""
        if not _interop.is_dataarray(da):
            raise Error(f"from_xarray takes an xarray.DataArray, got {type(da).__name__}")
        return cls._from_grid(_interop.dataarray_grid(da, _whole(band, "band")), _mapping(mapping), radius, length,
                              height_ref, origin)

    @classmethod
    def _from_grid(cls, grid, mapping, radius, length, height_ref=None, origin=None) -> "Terrain":
        return cls.from_array(grid.heights, grid.transform, grid.nodata, crs=grid.crs or None, unit=grid.unit or None,
                              mapping=mapping, radius=radius, length=length, height_ref=height_ref, origin=origin)

    @classmethod
    def from_array(cls, heights, transform, nodata=None, *, crs=None, unit=None, mapping: str = "cartesian",
                   radius=None, length=None, height_ref=None, origin=None) -> "Terrain":
        """A 2-D array (rows, columns) of heights as from_raster would read the same raster.

        transform: a GDAL geotransform (6 numbers) or an affine.Affine (rasterio's).
        nodata: pixels with this value are holes (so are NaN pixels, and masked pixels of a
            numpy.ma array).
        crs: the CRS, as any text GDAL reads ("EPSG:4326", WKT, PROJ) or an object with to_wkt()
            (rasterio's or pyproj's CRS); sets the ellipsoid of "geodetic" and the default
            radius of "spherical". None: no CRS (a lon/lat grid is then taken on WGS84).
        unit: the heights' unit, as a band's unit type ("m", "ft", "US survey foot", ...);
            spherical and cylindrical convert heights to metres with it, geodetic takes and gives
            heights in it. None: metres.
        mapping, radius, length, height_ref: as for from_raster (a compound crs states the heights'
            reference: "EPSG:4326+5773").
        """
        return cls(_qota._Terrain.from_array(_heights_array(heights), _interop.gdal_transform(transform),
                                             None if nodata is None else float(nodata), _interop.crs_text(crs),
                                             "" if unit is None else str(unit), _mapping(mapping),
                                             _number_or_none(radius, "radius"), _number_or_none(length, "length"),
                                             "" if height_ref is None else _os.fspath(height_ref), _origin(origin)))

    @classmethod
    def from_mesh(cls, vertices, triangles, *, mapping: str = "cartesian", origin=None) -> "Terrain":
        """An (N, 3) float array of vertices and an (M, 3) integer array of triangles, in world
        coordinates of the mapping's default frame: cartesian with gravity -z; spherical about the
        origin; geodetic in ECEF metres on WGS84; cylindrical about the z axis; enu: ECEF metres
        seen east-north-up from origin=(lat, lon[, h]), by default the ellipsoid point under the
        centre of the vertices' box (as `qota sample MESH --mapping enu`)."""
        triangles = _np.asarray(triangles)
        if triangles.size and not _np.issubdtype(triangles.dtype, _np.integer):
            raise Error(f"triangles must be integers (vertex indices), got {triangles.dtype}")
        return cls(_qota._Terrain.from_mesh(_coords(vertices, "vertices"), triangles.astype(_np.int64, copy=False),
                                            _mapping(mapping), _origin(origin)))

    @classmethod
    def load(cls, path) -> "Terrain":
        """A tree file written by save or `qota build`, in the mapping it was built in (see
        `mapping`). A geodetic tree keeps its raster's vertical unit."""
        return cls(_qota._Terrain.load(_local_file(path)))

    def save(self, path) -> None:
        """Writes the terrain with its quadtree and mapping (a tree file; load reads it back)."""
        self._t.save(str(path))

    @property
    def mapping(self) -> str:
        """The terrain's mapping: one of MAPPINGS."""
        return self._t.mapping

    @property
    def height_ref(self) -> str | None:
        """What the heights are over (geodetic): "ellipsoid", or the geoid with why ("EGM96
        geoid (egm96_15.gtx); assumed: ..."); None in the other mappings."""
        return self._t.height_ref or None

    @property
    def crs(self) -> str | None:
        """The source raster's CRS as WKT, or None (a mesh, a raster without one)."""
        return self._t.crs or None

    def _call(self, method, **arrays):
        b = _broadcast(**arrays)
        return method(*[_flat(a) for a in b]).reshape(b[0].shape)

    def hits(self, x, y, z=None, *, side: str = "top", normals: bool = True) -> "Hits":
        """The surface hit at each point, as a Hits (height, polygon, normal): side "top" (the
        top surface at each (x, y); z not given), "below" or "above" (the nearest surface at or
        below / at or above z at each (x, y, z)). height is NaN and polygon -1 where there is
        none; normal is the unit normal in the world frame (shape + (3,), NaN where none), or
        None with normals=False (a longitude/latitude raster in the cartesian mapping has no
        normals in one unit: ask with normals=False, or load it with mapping="geodetic")."""
        if side not in ("top", "below", "above"):
            raise Error(f"side must be 'top', 'below' or 'above', got {side!r}")
        if (side == "top") != (z is None):
            raise Error("z is given for side='below' or 'above', and only there")
        if normals and self._t._lon_lat_map:
            raise Error("normals of a longitude/latitude raster in the cartesian mapping would mix degrees and "
                        "metres (its heights are right); pass normals=False, load it with mapping='geodetic', "
                        "or reproject it")
        b = _broadcast(x=x, y=y) if z is None else _broadcast(x=x, y=y, z=z)
        shape = b[0].shape
        flat = [_flat(a) for a in b]
        h, p, n = self._t.hits(flat[0], flat[1], flat[2] if len(flat) > 2 else None, side)
        return Hits(h.reshape(shape), p.reshape(shape), n.reshape(shape + (3,)) if normals else None)

    def _flagged(self, name, side, polygons, normals, **arrays):
        # The 0.2 form: a tuple whose length follows the flags. Kept for a release, warned.
        _warnings.warn(f"{name}(..., polygons=, normals=) is deprecated: use hits(..., side={side!r}), whose "
                       "result is always a Hits (height, polygon, normal)", DeprecationWarning, stacklevel=3)
        hit = self.hits(arrays["x"], arrays["y"], arrays.get("z"), side=side, normals=normals)
        return tuple([hit.height] + ([hit.polygon] if polygons else []) + ([hit.normal] if normals else []))

    def heights(self, x, y, *, polygons=False, normals=False):
        """The top surface's height at each (x, y) (the mapping's coordinates); NaN where there is
        none. (Polygon ids and normals: hits(x, y). The polygons= and normals= flags of 0.2 still
        return a tuple, with a DeprecationWarning.)"""
        if polygons or normals:
            return self._flagged("heights", "top", polygons, normals, x=x, y=y)
        return self._call(self._t.heights, x=x, y=y)

    def below(self, x, y, z, *, polygons=False, normals=False):
        """The height of the nearest surface at or below z at each (x, y, z); NaN if none.
        (Polygon ids and normals: hits(x, y, z, side="below").)"""
        if polygons or normals:
            return self._flagged("below", "below", polygons, normals, x=x, y=y, z=z)
        return self._call(self._t.below, x=x, y=y, z=z)

    def above(self, x, y, z, *, polygons=False, normals=False):
        """The height of the nearest surface at or above z at each (x, y, z); NaN if none.
        (Polygon ids and normals: hits(x, y, z, side="above").)"""
        if polygons or normals:
            return self._flagged("above", "above", polygons, normals, x=x, y=y, z=z)
        return self._call(self._t.above, x=x, y=y, z=z)

    def bracket(self, x, y, z, *, polygons=False, normals=False):
        """(below, above): the floor's and the ceiling's heights around each point. (Polygon ids
        and normals: hits with side="below" and "above".)"""
        return (self.below(x, y, z, polygons=polygons, normals=normals),
                self.above(x, y, z, polygons=polygons, normals=normals))

    def all(self, x: float, y: float):
        """Every surface on the line of one point, top first: a list of (height, polygon,
        normal)."""
        return self._t.all(float(x), float(y))

    def stats(self) -> dict:
        """Polygons, triangles, vertices, quadtree nodes and bytes held."""
        return self._t.stats()

    def __repr__(self) -> str:
        s = self.stats()
        return f"qota.Terrain({self._t.source!r}, {self.mapping}: {s['triangles']} triangles)"


def _hours_span(hours):
    """hours=(start, end, step) as three floats for the C++ side (which checks their values)."""
    if hours is None:
        return None
    try:
        start, end, step = (float(v) for v in hours)
    except (TypeError, ValueError):
        raise Error(f"hours must be (start, end, step) in hours, got {hours!r}") from None
    return start, end, step


def _vector(value, name, n):
    """A light vector (or place) argument as n floats, or None; qota.Error naming it otherwise."""
    if value is None:
        return None
    try:
        v = [float(x) for x in value]
    except (TypeError, ValueError):
        raise Error(f"{name} must be {n} numbers, got {value!r}") from None
    if len(v) != n:
        raise Error(f"{name} must be {n} numbers, got {len(v)}")
    return v


#: The tools' options as the Python arguments that give them, for the tools' messages.
_ARGUMENTS = {
    "shadow": {"-az/-alt": "azimuth/altitude", "-az": "azimuth", "-alt": "altitude", "--time": "time", "--tz": "tz",
               "--hours": "hours", "-z/--z-factor": "z_factor", "--z-factor": "z_factor", "-z": "z_factor",
               "--height-ref": "height_ref", "--sun-vector-body": "sun_vector_body", "--sun-vector": "sun_vector",
               "--subsolar": "subsolar", "--flat": "flat", "--png": "png", "-b": "band", "--band": "band"},
    "viewshed": {"--observer-height": "observer_height", "--oz": "observer_height",
                 "--target-height": "target_height", "--tz": "target_height", "--max-distance": "max_distance",
                 "--md": "max_distance", "--refraction": "refraction", "--observers": "observers",
                 "--observer": "observer", "--srs": "srs", "--height-ref": "height_ref", "--flat": "flat",
                 "-b": "band", "--band": "band"},
}


@_contextlib.contextmanager
def _in_python_terms(tool):
    """A tool's qota.Error told in the Python call's terms: the argument names instead of the
    command's options, without the "qota <tool>:" prefix."""
    try:
        yield
    except Error as e:
        names = _ARGUMENTS[tool]
        pattern = r"(?<![\w-])(" + "|".join(_re.escape(k) for k in sorted(names, key=len, reverse=True)) + r")(?![\w-])"
        message = _re.sub(pattern, lambda m: names[m.group(1)], str(e))
        message = message.removeprefix(f"qota {tool}: ")
        raise Error(message) from None


def _shadow_file(dem_path, output, azimuth, altitude, time, tz, band, z_factor, hours, height_ref=None, light=None):
    """qota shadow on a raster file, into `output` (or a temporary file), as a uint8 array (float32
    hours with `hours`). light: sun_vector, sun_vector_body, subsolar, flat."""
    light = light or {}

    def run(path):
        png = light.get("png")
        with _in_python_terms("shadow"):
            return _qota._shadow(dem_path, path, azimuth, altitude, time or "", tz or "", int(band), float(z_factor),
                                 _hours_span(hours), "" if height_ref is None else _os.fspath(height_ref),
                                 _vector(light.get("sun_vector"), "sun_vector", 3),
                                 _vector(light.get("sun_vector_body"), "sun_vector_body", 3),
                                 _vector(light.get("subsolar"), "subsolar", 2), bool(light.get("flat", False)),
                                 "" if png is None else _os.fspath(png))

    if output is not None:
        return run(str(output))
    with _tempfile.TemporaryDirectory(prefix="qota_shadow_") as folder:
        return run(_os.path.join(folder, "shadow.tif"))


def _on_a_file(dem, band, compute):
    """compute(path, band) on a raster file holding a DataArray's or a rasterio dataset's band,
    and the DataArray its result goes into (its dimensions, coordinates and CRS).

    The C++ tools read a file: a dataset on a local file is read from that file, anything else is
    written to a temporary GeoTIFF first (float64, with its geotransform, nodata, CRS and
    vertical unit, which the tools use to put heights in metres)."""
    if _interop.is_rasterio_dataset(dem):
        template = _interop.dataarray_of_rasterio(dem, int(band))
        local = _interop.local_file_of(dem)
        grid = None if local is not None else _interop.rasterio_grid(dem, int(band))
    else:
        template = _interop.select_band(dem, int(band))
        local, grid = None, _interop.dataarray_grid(dem, int(band))
    if local is not None:
        return template, compute(local, band)
    with _tempfile.TemporaryDirectory(prefix="qota_raster_") as folder:
        path = _os.path.join(folder, "dem.tif")
        _qota._write_raster(path, grid.heights, grid.transform, grid.nodata, grid.crs, grid.unit)
        return template, compute(path, 1)


def _shadow_in_memory(dem, azimuth, altitude, time, tz, band, z_factor, output, hours, png=None):
    """qota shadow of a DataArray or a rasterio dataset, as a DataArray on its grid."""
    template, mask = _on_a_file(
        dem, band, lambda path, b: _shadow_file(path, output, azimuth, altitude, time, tz, b, z_factor, hours,
                                                light={"png": png}))
    if hours is not None:
        return _interop.mask_like(template, mask, -1.0, "sunlight_hours")
    return _interop.mask_like(template, mask)


def shadow(dem_path, azimuth=None, altitude=None, *, time=None, tz=None, hours=None, band=1, z_factor=1.0,
           output=None, height_ref=None, sun_vector=None, sun_vector_body=None, subsolar=None, flat=False,
           png=None):
    """Where the terrain of a DEM shades itself from the Sun, as `qota shadow` computes it.

    dem_path: a raster file, or an xarray.DataArray (rioxarray) or an open rasterio dataset.
    The light from `azimuth` and `altitude` (degrees, gdaldem's -az and -alt), or the Sun at
    `time` (ISO 8601 with its offset, or `tz`: an offset or an IANA zone name) seen from the DEM's
    centre. Heights are put in metres by the raster's vertical unit (a DataArray's `units`
    attribute), times z_factor. Returns uint8 pixels on the DEM's grid: 255 lit, 0 shadow, 128
    nodata; a numpy array (rows, columns) for a file, an xarray.DataArray for a DataArray or a
    rasterio dataset (its dimensions, coordinates and CRS, nodata 128; a 3-D DEM's band dimension
    kept with the one band used). With `output` the GeoTIFF (or any GDAL format by extension) is
    kept there too.

    hours: (start, end, step): instead, float32 hours of direct sunlight (nodata -1) between the
    local clock times start and end (0 to 48) of `time`'s date, in steps of `step` hours, a pixel
    lit at a step's middle counting the whole step (`qota shadow --hours`).

    height_ref: on the ellipsoid, what the heights are over ("ellipsoid", "egm96", "egm2008", "crs",
    a geoid grid's path; default: the raster's vertical CRS, else EGM96 on the Earth), as
    `qota shadow --height-ref`; a raster file only.

    Other lights, as the tool's: sun_vector=(east, north, up) at the DEM's centre;
    sun_vector_body=(x, y, z) toward the Sun in the body-fixed, body-centred frame (SPICE's spkpos
    in IAU_MARS); subsolar=(lon, lat), the Sun over that point (planetocentric latitude). flat:
    no curvature (qota shadow --flat). -az/-alt and sun_vector are refused at a pole.

    png: also write a PNG preview there (the mask, or the hours, over a hillshade; `qota shadow
    --png`). Errors (qota.Error) name these arguments.

    For a raster in chunks, over Dask: qota.dask.shadow.
    """
    light = {"sun_vector": sun_vector, "sun_vector_body": sun_vector_body, "subsolar": subsolar, "flat": flat,
             "png": png}
    others = sum(v is not None for v in (sun_vector, sun_vector_body, subsolar))
    if time is None and others == 0 and (azimuth is None or altitude is None):
        raise Error("give azimuth and altitude, or time, sun_vector, sun_vector_body or subsolar")
    azimuth = None if azimuth is None else _number(azimuth, "azimuth")
    altitude = None if altitude is None else _number(altitude, "altitude")
    band, z_factor = _whole(band, "band"), _number(z_factor, "z_factor")
    if time is not None and not isinstance(time, str):
        raise Error(f"time must be an ISO 8601 text, got {time!r}")
    if tz is not None and not isinstance(tz, str):
        raise Error(f"tz must be a text (an offset or an IANA zone name), got {tz!r}")
    if _interop.is_dataarray(dem_path) or _interop.is_rasterio_dataset(dem_path):
        if height_ref is not None or others or flat:
            raise Error("height_ref, sun_vector, sun_vector_body, subsolar and flat take a raster file; give the "
                        "DataArray's or dataset's file")
        return _shadow_in_memory(dem_path, azimuth, altitude, time, tz, band, z_factor, output, hours, png)
    return _shadow_file(_local_file(dem_path), output, azimuth, altitude, time, tz, band, z_factor, hours, height_ref,
                        light)


def viewshed(dem, observer, *, observer_height=2.0, target_height=0.0, max_distance=0.0, srs=None, band=1,
             flat=False, height_ref=None, refraction=0.0, output=None):
    """Which pixels of a DEM an observer sees, as `qota viewshed` computes it: exactly, on the
    triangulated terrain (a pixel is visible when the segment from the observer to its centre
    meets no terrain between its ends; voids block nothing), on the DEM's ellipsoid with straight
    geocentric lines unless `flat`.

    dem: a raster file, or an xarray.DataArray (rioxarray) or an open rasterio dataset.
    observer: (x, y) in the raster's CRS, or in `srs` (EPSG:4326, WKT, PROJ; x = longitude or
    easting). observer_height and target_height: metres above the surface at the observer and at
    each pixel centre (0 to MAX_HEIGHT, 1e9); max_distance: metres (horizontal), 0 for no limit.
    height_ref: on the ellipsoid, what the heights are over (as qota.shadow's; a raster file only). Returns uint8
    pixels on the DEM's grid: 255 visible, 0 not visible, 128 nodata, 64 beyond max_distance; a
    numpy array (rows, columns) for a file, an xarray.DataArray for a DataArray or a rasterio
    dataset. With `output` the raster is kept there too. refraction: the coefficient k of the
    standard model (0.13 is usual for the Earth; `qota viewshed --refraction`), on the ellipsoid.
    """
    if observer is None:
        raise Error("observer must be (x, y), got None")
    x, y = _vector(observer, "observer", 2)
    heights = {"observer_height": _height(observer_height, "observer_height"),
               "target_height": _height(target_height, "target_height"),
               "max_distance": _number(max_distance, "max_distance")}
    if not heights["max_distance"] >= 0:
        raise Error(f"max_distance must be a number of metres, 0 or more, got {heights['max_distance']!r}")
    if srs is not None and not isinstance(srs, str):
        raise Error(f"srs must be a text (EPSG:4326, WKT, PROJ), got {srs!r}")

    def run(path, b, kept):
        with _in_python_terms("viewshed"):
            return _qota._viewshed(path, kept, (x, y), srs or "", heights["observer_height"],
                                   heights["target_height"], heights["max_distance"], _whole(b, "band"), bool(flat),
                                   "" if height_ref is None else _os.fspath(height_ref),
                                   _number(refraction, "refraction"))

    def on_file(path, b):
        if output is not None:
            return run(path, b, str(output))
        with _tempfile.TemporaryDirectory(prefix="qota_viewshed_") as folder:
            return run(path, b, _os.path.join(folder, "viewshed.tif"))

    if _interop.is_dataarray(dem) or _interop.is_rasterio_dataset(dem):
        if height_ref is not None:
            raise Error("height_ref takes a raster file; give the DataArray's or dataset's file")
        template, seen = _on_a_file(dem, band, on_file)
        return _interop.mask_like(template, seen, 128, "viewshed")
    return on_file(_local_file(dem), band)


def _is_geodataframe(value):
    return hasattr(value, "geometry") and hasattr(value, "crs") and hasattr(value, "assign")


def sample(dem, x, y=None, *, band=1, resampling="triangle", srs=None, field="height"):
    """Heights of a raster under points, streamed as `qota sample` reads it: tile by tile, so a
    raster of any size (a VRT of a continent) is sampled in bounded memory, without loading it.

    dem: a raster file (or any GDAL name), an open rasterio dataset or an xarray.DataArray.
    x, y: coordinates of any shape (broadcast together), in the raster's CRS or in `srs`
    (EPSG:4326, WKT, PROJ; x = longitude or easting). Or x alone a geopandas GeoDataFrame of
    points: a copy of it is returned with a column `field` of heights, its points taken in its own
    CRS (`srs` when it has none). resampling (qota.RESAMPLINGS): "triangle", the exact surface of
    the raster's triangles (Terrain.from_raster(dem).heights(x, y), bit for bit); "nearest", the
    pixel containing the point (what gdallocationinfo prints); "bilinear" and "cubic", GDAL's
    kernels on pixel centres with its nodata rules. Returns float64 heights in the raster's
    vertical unit, NaN where there is none (a void, off the raster, an empty geometry).
    """
    if resampling not in RESAMPLINGS:
        raise Error(f"resampling must be one of {', '.join(RESAMPLINGS)}, got {resampling!r}")
    if srs is not None and not isinstance(srs, str):
        raise Error(f"srs must be a text (EPSG:4326, WKT, PROJ), got {srs!r}")
    frame = None
    if y is None:
        if not _is_geodataframe(x):
            raise Error("give x and y, or a geopandas GeoDataFrame of points as x")
        frame = x
        if field in frame.columns:
            raise Error(f"the GeoDataFrame already has a column {field!r}; name the heights' column with field=")
        geometry = frame.geometry
        empty = (geometry.isna() | geometry.is_empty).to_numpy()
        kinds = set(geometry[~empty].geom_type) - {"Point"}  # (an empty point may say GeometryCollection)
        if kinds:
            raise Error(f"the GeoDataFrame's geometries must be points, not {', '.join(sorted(kinds))}")
        points = geometry[~empty]
        x, y = _np.full(len(frame), _np.nan), _np.full(len(frame), _np.nan)
        x[~empty], y[~empty] = points.x.to_numpy(dtype=_np.float64), points.y.to_numpy(dtype=_np.float64)
        if frame.crs is not None:
            srs = frame.crs.to_wkt()
    xs, ys = _broadcast(x=x, y=y)

    def on_file(path, b):
        sampler = _qota._RasterSampler(path, _whole(b, "band"), resampling, srs or "")
        return sampler.heights(_flat(xs), _flat(ys)).reshape(xs.shape)

    if _interop.is_dataarray(dem) or _interop.is_rasterio_dataset(dem):
        heights = _on_a_file(dem, band, on_file)[1]
    else:
        heights = on_file(_local_file(dem), band)
    return heights if frame is None else frame.assign(**{field: heights})


def sun_position(time, lon, lat, *, tz=None):
    """The Sun's apparent (azimuth, altitude) in degrees seen from (lon, lat) on the Earth at `time`
    (ISO 8601 with its offset, or `tz`); azimuth clockwise from north, refraction included."""
    return _qota._sun_position(str(time), float(lon), float(lat), tz or "")
