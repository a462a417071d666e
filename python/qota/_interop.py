"""Rasters that are already open in Python: rasterio datasets and xarray DataArrays (with
rioxarray's `rio` accessor), turned into what the C++ side reads (a file path, or an array with its
geotransform, nodata, CRS and vertical unit), and shadow masks turned back into DataArrays.

Nothing here imports rasterio or xarray at module level: the package works without them, and an
object can only be one of theirs if its library is already imported (sys.modules tells).
"""
from __future__ import annotations

import os
import sys
from dataclasses import dataclass

import numpy as np

from ._qota import Error


@dataclass
class Grid:
    """One band of a raster in memory: heights (rows, columns) in float64, with NaN or `nodata`
    for no data, a GDAL geotransform, and the CRS and vertical unit as text ("" when unknown)."""

    heights: np.ndarray
    transform: list
    nodata: float | None
    crs: str
    unit: str


def is_dataarray(obj) -> bool:
    xr = sys.modules.get("xarray")
    return xr is not None and isinstance(obj, xr.DataArray)


def is_xarray_dataset(obj) -> bool:
    xr = sys.modules.get("xarray")
    return xr is not None and isinstance(obj, xr.Dataset)


def is_rasterio_dataset(obj) -> bool:
    # Duck-typed on rasterio's own classes (DatasetReader, DatasetWriter, ...), whose common base
    # lives in a private module.
    return (type(obj).__module__.split(".")[0] == "rasterio" and hasattr(obj, "read")
            and hasattr(obj, "transform") and hasattr(obj, "nodatavals"))


def gdal_transform(transform) -> list:
    """A GDAL 6-tuple geotransform, from one or from an affine.Affine (rasterio's)."""
    if all(hasattr(transform, k) for k in "abcdef"):  # affine.Affine: x = a col + b row + c
        t = transform
        return [float(v) for v in (t.c, t.a, t.b, t.f, t.d, t.e)]
    try:
        values = [float(v) for v in transform]
    except (TypeError, ValueError) as e:
        raise Error(f"transform must be 6 numbers (GDAL's geotransform) or an affine.Affine: {e}") from None
    if len(values) != 6:
        raise Error(f"transform must have 6 numbers (GDAL's geotransform), got {len(values)}")
    return values


def crs_text(crs) -> str:
    """A CRS as text GDAL reads: a string as it is (WKT, "EPSG:4326", PROJ), an object with
    to_wkt() (rasterio's or pyproj's CRS) as its WKT, None as ""."""
    if crs is None:
        return ""
    if isinstance(crs, str):
        return crs
    if hasattr(crs, "to_wkt"):
        return crs.to_wkt()
    raise Error(f"crs must be a string (WKT, EPSG:code, PROJ) or a CRS object with to_wkt(), got {type(crs).__name__}")


def _decoded(raw: np.ndarray, nodata, scale: float, offset: float):
    """Heights from a band's stored values: scaled and offset as GDAL's GetScale and GetOffset say
    (so as loadDem reads a file), the nodata pixels NaN. Returns (heights, nodata to declare)."""
    if scale == 1 and offset == 0:
        return np.asarray(raw, dtype=np.float64), nodata
    heights = np.asarray(raw, dtype=np.float64) * scale + offset
    if nodata is not None:
        heights[np.asarray(raw) == nodata] = np.nan  # compared as stored, before the scale
    return heights, None


def local_file_of(ds) -> str | None:
    """The file a rasterio dataset reads, when it is a local file opened read-only: qota then opens
    that file itself (everything the file says, the vertical unit too). None for a dataset in
    memory or being written, whose pixels only the dataset has."""
    if ds.closed:
        raise Error(f"the rasterio dataset {ds.name} is closed")
    name = str(ds.name)
    if ds.mode == "r" and os.path.isfile(name):
        return name
    return None


def rasterio_grid(ds, band: int) -> Grid:
    """Band `band` (1-based) of an open rasterio dataset, read through rasterio."""
    if ds.closed:
        raise Error(f"the rasterio dataset {ds.name} is closed")
    if not 1 <= band <= ds.count:
        raise Error(f"{ds.name}: no band {band} (the dataset has {ds.count})")
    i = band - 1
    heights, nodata = _decoded(ds.read(band), ds.nodatavals[i], ds.scales[i], ds.offsets[i])
    return Grid(heights, gdal_transform(ds.transform), nodata, crs_text(ds.crs), ds.units[i] or "")


def _rio():
    """rioxarray, imported for its `rio` accessor (xarray alone knows no geotransform or CRS)."""
    try:
        import rioxarray  # noqa: F401  (registers DataArray.rio)
    except ImportError as e:
        raise ImportError("a DataArray terrain needs rioxarray (Debian: python3-rioxarray) for its "
                          "geotransform and CRS") from e


def select_band(da, band: int):
    """The DataArray of one band: a 2-D (y, x) array as it is; a 3-D one at position `band`
    (1-based) of its third dimension (rioxarray's `band`), kept as a dimension of length 1."""
    _rio()
    y, x = da.rio.y_dim, da.rio.x_dim
    others = [d for d in da.dims if d not in (y, x)]
    if not others:
        return da
    if len(others) > 1:
        raise Error(f"a DataArray with dimensions {da.dims}: give one 2-D band (y, x) or a 3-D (band, y, x)")
    size = da.sizes[others[0]]
    if not 1 <= band <= size:
        raise Error(f"the DataArray has no band {band} (its {others[0]!r} dimension has {size})")
    return da.isel({others[0]: [band - 1]})


def _stored_transform(da):
    """The GeoTransform kept with the DataArray's CRS (as GDAL wrote it), or None."""
    name = da.rio.grid_mapping
    text = da.coords[name].attrs.get("GeoTransform") if name in da.coords else None
    if not text:
        return None
    try:
        values = [float(v) for v in str(text).split()]
    except ValueError:
        return None
    return values if len(values) == 6 else None


def dataarray_transform(da) -> list:
    """The DataArray's geotransform: rioxarray's, from the coordinates (a sliced array's own), or
    the stored GeoTransform where it agrees with them, since the coordinates are the pixel centres
    rounded once more (the origin back from them can be an ulp off the file's)."""
    computed = gdal_transform(da.rio.transform())
    stored = _stored_transform(da)
    if stored is None:
        return computed
    pixel = max(abs(computed[1]) + abs(computed[2]), abs(computed[4]) + abs(computed[5]))
    same = all(abs(s - c) <= 1e-6 * pixel for s, c in zip(stored, computed))
    return stored if same else computed


def dataarray_grid(da, band: int) -> Grid:
    """One band of a DataArray with rioxarray's accessor: its values in (y, x) order, the
    geotransform, `rio.nodata` (NaN pixels are holes too), `rio.crs` and the `units` attribute.
    Raw values with `scale_factor`/`add_offset` attributes (open_rasterio without
    mask_and_scale) are decoded as GDAL would."""
    da = select_band(da, band)
    y, x = da.rio.y_dim, da.rio.x_dim
    plane = da.squeeze([d for d in da.dims if d not in (y, x)]).transpose(y, x)
    units = da.attrs.get("units", "")
    scale = float(da.attrs.get("scale_factor", 1.0))
    offset = float(da.attrs.get("add_offset", 0.0))
    nodata = da.rio.nodata
    heights, nodata = _decoded(np.asarray(plane.values), None if nodata is None else float(nodata), scale, offset)
    return Grid(heights, dataarray_transform(plane), nodata, crs_text(da.rio.crs),
                units if isinstance(units, str) else "")


def dataarray_of_rasterio(ds, band: int):
    """A rasterio dataset's band as a DataArray (rioxarray reads it lazily), for a shadow mask's
    coordinates."""
    _rio()
    import rioxarray

    return select_band(rioxarray.open_rasterio(ds), band)


def mask_like(template, mask, nodata=128, name="shadow"):
    """The shadow mask (rows, columns) as a DataArray on the template's grid: its dimensions,
    coordinates and CRS, with `nodata` declared (128 for a mask, -1 for hours); the heights' own
    attributes (units, scale) left behind. A dask array stays lazy."""
    import xarray as xr

    y, x = template.rio.y_dim, template.rio.x_dim
    plane = xr.DataArray(mask, dims=(y, x))
    others = [d for d in template.dims if d not in (y, x)]
    if others:
        plane = plane.expand_dims(others)
    out = template.copy(data=plane.transpose(*template.dims).data)
    out.attrs, out.encoding, out.name = {}, {}, name
    if template.rio.crs is not None:
        out = out.rio.write_crs(template.rio.crs)
    # The template's geotransform kept with the CRS, so a writer that reads it (rio.to_raster with
    # recalc_transform=False) writes the file's, not one recomputed from the rounded coordinates.
    from affine import Affine

    out = out.rio.write_transform(Affine.from_gdal(*dataarray_transform(template)))
    return out.rio.write_nodata(nodata, encoded=False)
