"""qota: terrain heights under points, from rasters, numpy arrays and meshes.

The Quick Oriented Terrain Algorithm's quadtree core, for numpy: every call takes arrays of any
shape (broadcast together), answers in C++ on every core with the GIL released, and gives NaN
where there is no terrain (a hole, nodata, outside the data).

    >>> import qota
    >>> t = qota.Terrain.from_raster("data/mt_rainier_90m.tif")
    >>> t.heights([-121.7603], [46.8529])          # x, y in the raster's CRS
    array([4367.4...])
"""
from __future__ import annotations

import errno as _errno
import os as _os
import tempfile as _tempfile

import numpy as _np

from . import _qota
from ._qota import Error, __version__

__all__ = ["Terrain", "Error", "__version__", "shadow", "sun_position"]


def _gdal_transform(transform):
    """A GDAL 6-tuple geotransform, from one or from an affine.Affine (rasterio's)."""
    if all(hasattr(transform, k) for k in "abcdef"):  # affine.Affine: x = a col + b row + c
        t = transform
        return [t.c, t.a, t.b, t.f, t.d, t.e]
    values = [float(v) for v in transform]
    if len(values) != 6:
        raise Error(f"transform must have 6 numbers (GDAL's geotransform), got {len(values)}")
    return values


def _local_file(path):
    """A local path that is not there is FileNotFoundError (an OSError), as Python's own open()
    gives; GDAL's virtual paths (/vsicurl/...) and connection strings (NAME:...) go to GDAL."""
    text = _os.fspath(path)
    if not text.startswith("/vsi") and ":" not in text and not _os.path.exists(text):
        raise FileNotFoundError(_errno.ENOENT, "no such file", text)
    return text


class Terrain:
    """A terrain seen from above (gravity along -z): the surfaces over each (x, y).

    Build one with from_raster, from_array or from_mesh (or load a file saved by save or
    `qota build`). Queries take x, y (and z) in the terrain's own coordinates and give heights in
    its own z unit.
    """

    def __init__(self, impl: _qota._Terrain):
        self._t = impl

    @classmethod
    def from_raster(cls, path, band: int = 1) -> "Terrain":
        """Any GDAL raster (GeoTIFF, VRT, ...): pixel centres joined into two triangles a cell,
        nodata cells holes, x and y in the raster's CRS (degrees for a lon/lat raster)."""
        return cls(_qota._Terrain.from_raster(_local_file(path), int(band)))

    @classmethod
    def from_array(cls, heights, transform, nodata=None) -> "Terrain":
        """A 2-D array (rows, columns) of heights with a GDAL geotransform (6 numbers) or an
        affine.Affine, as from_raster would read the same raster; `nodata` cells are holes."""
        return cls(_qota._Terrain.from_array(_np.asarray(heights, dtype=_np.float64),
                                             _gdal_transform(transform),
                                             None if nodata is None else float(nodata)))

    @classmethod
    def from_mesh(cls, vertices, triangles) -> "Terrain":
        """An (N, 3) float array of vertices and an (M, 3) integer array of triangles."""
        triangles = _np.asarray(triangles)
        if triangles.size and not _np.issubdtype(triangles.dtype, _np.integer):
            raise Error(f"triangles must be integers (vertex indices), got {triangles.dtype}")
        return cls(_qota._Terrain.from_mesh(_np.asarray(vertices, dtype=_np.float64),
                                            triangles.astype(_np.int64, copy=False)))

    @classmethod
    def load(cls, path) -> "Terrain":
        """A tree file written by save or `qota build` (a Cartesian terrain)."""
        return cls(_qota._Terrain.load(_local_file(path)))

    def save(self, path) -> None:
        """Writes the terrain with its quadtree (a tree file; load reads it back)."""
        self._t.save(str(path))

    def _call(self, method, *arrays):
        b = _np.broadcast_arrays(*[_np.asarray(a, dtype=_np.float64) for a in arrays])
        flat = [_np.ascontiguousarray(a).ravel() for a in b]
        return method(*flat).reshape(b[0].shape)

    def _hits(self, x, y, z, below, polygons, normals):
        b = _np.broadcast_arrays(*[_np.asarray(a, dtype=_np.float64) for a in (x, y, z)])
        shape = b[0].shape
        h, p, n = self._t.hits(*[_np.ascontiguousarray(a).ravel() for a in b], below)
        out = [h.reshape(shape)]
        if polygons:
            out.append(p.reshape(shape))
        if normals:
            out.append(n.reshape(shape + (3,)))
        return tuple(out)

    def heights(self, x, y, *, polygons=False, normals=False):
        """The top surface's height at each (x, y); NaN where there is none.

        With polygons=True and/or normals=True, a tuple: the heights, then the polygon ids (int64,
        -1 where none) and/or the unit normals (shape + (3,), NaN where none)."""
        if polygons or normals:
            return self._hits(x, y, _np.inf, True, polygons, normals)
        return self._call(self._t.heights, x, y)

    def below(self, x, y, z, *, polygons=False, normals=False):
        """The height of the nearest surface at or below z at each (x, y, z); NaN if none.
        polygons and normals as for heights."""
        if polygons or normals:
            return self._hits(x, y, z, True, polygons, normals)
        return self._call(self._t.below, x, y, z)

    def above(self, x, y, z, *, polygons=False, normals=False):
        """The height of the nearest surface at or above z at each (x, y, z); NaN if none.
        polygons and normals as for heights."""
        if polygons or normals:
            return self._hits(x, y, z, False, polygons, normals)
        return self._call(self._t.above, x, y, z)

    def bracket(self, x, y, z, *, polygons=False, normals=False):
        """(below, above): the floor and the ceiling around each point (each a tuple with
        polygons and normals on request)."""
        return (self.below(x, y, z, polygons=polygons, normals=normals),
                self.above(x, y, z, polygons=polygons, normals=normals))

    def all(self, x: float, y: float):
        """Every surface over one point, top first: a list of (height, polygon, normal)."""
        return self._t.all(float(x), float(y))

    def stats(self) -> dict:
        """Polygons, triangles, vertices, quadtree nodes and bytes held."""
        return self._t.stats()

    def __repr__(self) -> str:
        s = self.stats()
        return f"qota.Terrain({self._t.source!r}: {s['triangles']} triangles)"


def shadow(dem_path, azimuth=None, altitude=None, *, time=None, tz=None, band=1, z_factor=1.0, output=None):
    """Where the terrain of a DEM shades itself from the Sun, as `qota shadow` computes it.

    The light from `azimuth` and `altitude` (degrees, gdaldem's -az and -alt), or the Sun at
    `time` (ISO 8601 with its offset, or `tz`: an offset or an IANA zone name) seen from the DEM's
    centre. Returns a uint8 array on the DEM's grid (rows, columns): 255 lit, 0 shadow, 128
    nodata; with `output` the GeoTIFF (or any GDAL format by extension) is kept there too.
    """
    if time is None and (azimuth is None or altitude is None):
        raise Error("give azimuth and altitude, or time")
    if output is not None:
        return _qota._shadow(_local_file(dem_path), str(output), azimuth, altitude, time or "", tz or "", int(band),
                             float(z_factor))
    with _tempfile.TemporaryDirectory(prefix="qota_shadow_") as folder:
        return _qota._shadow(_local_file(dem_path), _os.path.join(folder, "shadow.tif"), azimuth, altitude, time or "",
                             tz or "", int(band), float(z_factor))


def sun_position(time, lon, lat, *, tz=None):
    """The Sun's apparent (azimuth, altitude) in degrees seen from (lon, lat) on the Earth at `time`
    (ISO 8601 with its offset, or `tz`); azimuth clockwise from north, refraction included."""
    return _qota._sun_position(str(time), float(lon), float(lat), tz or "")
