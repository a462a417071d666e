"""qota.dask: shadows, hours of sunlight and heights under points over Dask, on any
`dask.distributed` cluster (or Dask's local schedulers).

    >>> import rioxarray, qota.dask
    >>> dem = rioxarray.open_rasterio("data/mt_rainier_90m.tif", chunks=512)
    >>> mask = qota.dask.shadow(dem, azimuth=135, altitude=20)   # lazy, on dem's blocks
    >>> qota.dask.to_geotiff(mask, "shadow.tif")                 # computed block by block

Shadows: every block of the DataArray is one task, which computes the block's pixels from the
block's heights and an overlap around it (the halo: every pixel whose triangles can shade the
block, as ShadowTiles.haloFor bounds it for blocks of that size, plus `void_margin` pixels for
filling voids as over the whole raster). The tiles (the raster's height range and frame, which the
halo and every block's frame need) are made once on the client, in one pass over the heights, and
reach the workers as a small pickled text. Each task calls the C++ core with the GIL released. The
result is the whole raster's, pixel for pixel: what qota.shadow gives for the same raster.

Viewsheds: how many of many observers see each pixel (viewsheds), the observers split into
groups, each group one task that places and indexes the raster and looks from its observers
(qota::cumulativeViewshed), the tasks' counts summed.

Points: heights under (x, y) points given as a dask DataFrame or array, each partition answered
by a sampler that reads the raster tile by tile (one per worker process, raster and call: a
raster rewritten between calls is read again, one rewritten after a call and before its
computation refused, and so is a VRT whose source file was, or any file GDAL reads for the
raster), bit for bit the whole terrain's (Terrain.from_raster).
"""
from __future__ import annotations

import os
import shutil
import threading
import uuid
from dataclasses import dataclass

import numpy as np

from . import MAX_HEIGHT, _height, _hours_span, _interop, _local_file, _number, _qota, _whole
from ._qota import Error

__all__ = ["shadow", "tiles", "Tiles", "sample", "to_geotiff", "to_zarr"]

#: Pixels of overlap added to the halo for filling voids (pixels without data) the same way as over
#: the whole raster: a void up to about this wide fills alike; a wider one near a block edge is
#: refused, naming the pixels, and then a larger void_margin (or voids filled first) is needed.
VOID_MARGIN = 32


def _is_dask(data) -> bool:
    from dask import is_dask_collection
    return is_dask_collection(data)


def _heights(raw, nodata, scale, offset):
    """A window's stored values as heights: scaled and offset as GDAL would, nodata pixels NaN."""
    heights, nodata = _interop._decoded(raw, nodata, scale, offset)
    heights = np.array(heights, dtype=np.float64)  # writable, its own
    if nodata is not None:
        heights[heights == nodata] = np.nan
    return heights


# --- the light ---------------------------------------------------------------------------------

def _check_light(azimuth, altitude, time, tz, hours):
    """Refuses a light the way `qota shadow` does, before any work (here the blocks' tasks would
    meet a bad option only when computed). The hours' (start, end, step), or None."""
    if time is None and (azimuth is None or altitude is None):
        raise Error("give azimuth and altitude, or time")
    if time is not None and (azimuth is not None or altitude is not None):
        raise Error("give one light: azimuth and altitude, or time")
    if tz is not None and time is None:
        raise Error("tz needs time (the date and time it is the zone of)")
    if hours is not None and time is None:
        raise Error("hours needs time for the date")
    if time is None:
        azimuth, altitude = _number(azimuth, "azimuth"), _number(altitude, "altitude")
    if time is None and not (-90 <= float(altitude) <= 90 and np.isfinite(float(azimuth))):
        raise Error(f"altitude must be between -90 and 90 degrees and azimuth finite, got {azimuth} {altitude}")
    if hours is not None:
        start, end, step = _hours_span(hours)
        _qota._check_hours(start, end, step)  # (qota shadow --hours's checks)
        return start, end, step
    return None


# --- the tiles ---------------------------------------------------------------------------------

def _plane(da, band):
    """The DataArray of one band (a 3-D one keeps its band dimension, of length 1) and its heights
    as a 2-D (y, x) array."""
    template = _interop.select_band(da, band)
    y, x = template.rio.y_dim, template.rio.x_dim
    return template, template.squeeze([d for d in template.dims if d not in (y, x)]).transpose(y, x)


def _source_file(plane):
    """The file the DataArray was read from (rioxarray's encoding) and its band, when the array
    still has that file's grid, nodata and unit (so the file's heights are the array's unless its
    values were changed in place); else None. Without a band coordinate, only a one-band file."""
    source = plane.encoding.get("source")
    if not source:
        return None
    file_band = int(plane.coords["band"]) if "band" in plane.coords and plane.coords["band"].size == 1 else 0
    try:
        described = _qota._describe_raster(str(source), file_band)
    except Error:
        return None
    nodata = plane.rio.encoded_nodata if plane.rio.encoded_nodata is not None else plane.rio.nodata
    same_nodata = (nodata is None) == (described["nodata"] is None) and (
        nodata is None or np.array_equal(float(nodata), described["nodata"], equal_nan=True))
    mine, theirs = _interop.dataarray_transform(plane), described["geotransform"]
    pixel = max(abs(theirs[1]) + abs(theirs[2]), abs(theirs[4]) + abs(theirs[5]))
    if ((described["height"], described["width"]) != plane.shape or not same_nodata
            or plane.attrs.get("units", "") != described["unit"]
            or any(abs(a - b) > 1e-6 * pixel for a, b in zip(mine, theirs))):
        return None
    return str(source), file_band


@dataclass(frozen=True)
class Tiles:
    """What every block of one raster's shadows shares (the height range, the frame), made once
    on the client by qota.dask.tiles in one pass over the heights: reused, it saves that pass
    when one raster is shadowed under several suns."""

    core: object        # qota._qota._ShadowTiles: pickled as a small text for the workers
    heights_from: str   # "file": the pass read the source file; "array": the array's blocks
    source: str         # the file, or "<DataArray name>"


def tiles(da, *, band=1, z_factor=1.0, heights_from="auto") -> Tiles:
    """The tiles of a DataArray's raster (band `band`, heights times z_factor), for shadow(...,
    tiles=). heights_from: where the one pass over the heights reads them: "file" (the source file
    rioxarray names in the array's encoding, read by GDAL on the client), "array" (the array's own
    blocks, computed through Dask a band of rows at a time), or "auto" (the file when the array
    still has its grid, nodata and unit, else the array). Give "array" for an array whose values
    were changed in a way that keeps rioxarray's encoding (assigned in place,
    da.copy(data=...))."""
    if heights_from not in ("auto", "file", "array"):
        raise Error(f"heights_from must be 'auto', 'file' or 'array', got {heights_from!r}")
    band, z_factor = _whole(band, "band"), _number(z_factor, "z_factor")
    plane = _plane(da, band)[1]
    if heights_from != "array":
        source = _source_file(plane)
        if source is not None:
            return Tiles(_qota._ShadowTiles.from_raster(source[0], source[1], float(z_factor)), "file", source[0])
        if heights_from == "file":
            raise Error("heights_from='file': the DataArray names no source file with its own grid, nodata and unit "
                        "(its encoding's 'source'); give heights_from='array'")
    decode = _decoding(plane)

    def read(col, row, width, height):
        return _heights(np.asarray(plane.data[row:row + height, col:col + width].compute()), *decode)

    label = f"<DataArray {plane.name}>" if plane.name is not None else "<DataArray>"
    units = plane.attrs.get("units", "")
    core = _qota._ShadowTiles.from_reader(plane.shape[0], plane.shape[1], _interop.dataarray_transform(plane),
                                          _interop.crs_text(plane.rio.crs), units if isinstance(units, str) else "",
                                          label, read, float(z_factor), int(band))
    return Tiles(core, "array", label)


_make_tiles = tiles  # for shadow(), whose keyword `tiles` hides the function


def _decoding(plane):
    """(nodata, scale, offset) of the stored values, as _interop.dataarray_grid reads them."""
    nodata = plane.rio.nodata
    return (None if nodata is None else float(nodata), float(plane.attrs.get("scale_factor", 1.0)),
            float(plane.attrs.get("add_offset", 0.0)))


# --- blocks with their overlap ---------------------------------------------------------------

def _checked(call, tiles, source):
    """call() with a hint added when the block's heights are not those the tiles were made from."""
    try:
        return call()
    except Error as e:
        if "are not those the shadow tiles were made from" not in str(e):
            raise
        raise Error(f"{e}. The tiles were made from {source}: give tiles made from this DataArray "
                    f"(qota.dask.tiles(da)), or, when its values were changed after it was read from its file, "
                    f"made from the array itself (heights_from='array')") from None


def _mask_block(tiles, raw, window, tile, decode, light, threads, source):
    return _checked(lambda: tiles.mask_from_heights(window, _heights(raw, *decode), tile, light, threads), tiles, source)


def _hours_block(tiles, raw, window, tile, decode, span, step, lights, threads, source):
    return _checked(lambda: tiles.hours_from_heights(window, _heights(raw, *decode), tile, span[0], span[1], step,
                                                     lights, threads), tiles, source)


def _by_blocks(data, overlap, tiles, task, dtype, *args):
    """A dask array on data's blocks: task(tiles, heights of the block and its overlap, window,
    tile, *args) for every block, the window being the block grown by overlap (west, east, north,
    south) and clipped to the raster, in raster pixels (col, row, width, height)."""
    import dask
    import dask.array as dsa
    from dask.base import tokenize

    rows, cols = data.shape
    shared = dask.delayed(tiles, name="qota-tiles-" + tokenize(tiles.state()))  # one copy, restored once a worker
    call = dask.delayed(task, pure=True)
    blocks = _blocks_of(data.chunks)
    # Whole hash blocks, so that the task can check the heights it is given.
    windows = _windows_of(tiles, blocks, overlap, rows, cols)
    pixels = [dsa.from_delayed(call(shared, data[r0:r0 + h, c0:c0 + w], (c0, r0, w, h), block, *args),
                              shape=(block[3], block[2]), dtype=dtype)
             for block, (c0, r0, w, h) in zip(blocks, windows)]
    across = len(data.chunks[1])
    return dsa.block([pixels[k:k + across] for k in range(0, len(pixels), across)])


def shadow(da, azimuth=None, altitude=None, *, time=None, tz=None, hours=None, band=1, z_factor=1.0,
           void_margin=VOID_MARGIN, heights_from="auto", tiles=None, threads=1, max_memory=None):
    """Shadows (or hours of sunlight) of a chunked DataArray, lazily, on its own blocks.

    da: an xarray.DataArray backed by a dask array, with rioxarray's accessor (e.g.
        rioxarray.open_rasterio(path, chunks=512)); a 3-D one gives band `band` (1-based) of its
        third dimension. The light and the values as qota.shadow: `azimuth` and `altitude`
        (degrees), or the Sun at `time` (ISO 8601 with its offset, or `tz`), seen from the DEM's
        centre; heights in metres by the vertical unit (the `units` attribute, or the file's),
        times z_factor.
    hours: (start, end, step): hours of direct sunlight between the local clock times start and
        end (0 to 48) of `time`'s date, in steps of `step` hours (qota shadow --hours).
    void_margin: pixels of overlap beyond the halo for filling voids; a void too wide for it near a
        block edge is refused when that block is computed (qota.Error, "give a larger overlap").
    heights_from: where the client's one pass over the heights reads them (see qota.dask.tiles).
    tiles: qota.dask.tiles of this DataArray (its band and z_factor), made before: no pass. Tiles of
        another grid, band or z_factor are refused at once, and every block checks its heights
        against the tiles' block hashes (another raster's heights on the same grid are refused
        when computed).
    threads: threads a block's pixels are tested on (0: every core); 1 suits workers that each run
        one task per core.
    max_memory: the most a task may take, in bytes or as a size ("2G", "512M"; what a worker
        thread has): blocks whose task would take more are computed as smaller square blocks (the
        result keeps da's chunks); refused when even blocks of 16 pixels need more (a low sun's
        halo). The estimate of a task's peak is the result's attrs["qota_task_memory"] (bytes),
        measured to bound the peak within 1.5 times.

    Chunks much smaller than the halo a block needs (a low sun's) are merged for the computation
    into square blocks whose overlap is at most MOST_OVERLAP times their pixels; the result is
    given back on da's chunks.

    Returns a lazy DataArray on da's grid, dimensions, coordinates, CRS and chunks: uint8 255 lit,
    0 shadow, 128 nodata; or float32 hours, nodata -1. Refuses at once what qota.shadow refuses
    (the light, the options). A low sun takes a large overlap (on the ellipsoid, up to the
    distance at which its rays clear the body's curve: a few hundred kilometres at the horizon).
    """
    span_hours = _check_light(azimuth, altitude, time, tz, hours)
    band, z_factor, threads = _whole(band, "band"), _number(z_factor, "z_factor"), _whole(threads, "threads", 0)
    void_margin = _whole(void_margin, "void_margin", 0)
    max_memory = None if max_memory is None else _size(max_memory, "max_memory")
    if not _interop.is_dataarray(da):
        raise Error(f"qota.dask.shadow takes an xarray.DataArray, got {type(da).__name__}")
    if int(void_margin) < 0:
        raise Error(f"void_margin must be a number of pixels (0 or more), got {void_margin}")
    template, plane = _plane(da, int(band))
    if not _is_dask(plane.data):
        raise Error("the DataArray is not chunked (not backed by a dask array): open it with chunks= "
                    "(rioxarray.open_rasterio(path, chunks=512)) or chunk it (da.chunk(512))")
    if tiles is None:  # (made from this very plane: nothing to check)
        tiles = _make_tiles(da, band=band, z_factor=z_factor, heights_from=heights_from)
    else:
        _check_tiles(tiles, plane, band, z_factor, heights_from)
    core = tiles.core
    if span_hours is None:
        sun = (azimuth, altitude) if time is None else core.sun_at(str(time), tz or "")
        lights = [core.toward_sun(float(sun[0]), float(sun[1]))]
    else:
        start, end, step = span_hours
        span = _qota._local_span(str(time), tz or "", start, end)
        lights = core.sunlight_steps(span[0], span[1], step)
    data, overlap, task_bytes = _blocks_for_halo(plane.data, core, lights, int(void_margin), max_memory)
    decode = _decoding(plane)
    if span_hours is None:
        pixels = _by_blocks(data, overlap, core, _mask_block, np.uint8, decode, lights[0], int(threads), tiles.source)
        result = _interop.mask_like(template, pixels.rechunk(plane.data.chunks), 128, "shadow")
    else:
        pixels = _by_blocks(data, overlap, core, _hours_block, np.float32, decode, span, span_hours[2], lights,
                           int(threads), tiles.source)
        result = _interop.mask_like(template, pixels.rechunk(plane.data.chunks), -1.0, "sunlight_hours")
    result.attrs["qota_task_memory"] = int(task_bytes)
    return result


def _size(value, name):
    """A size in bytes: a whole number, or a text as qota shadow --max-memory takes ("64M", "2G")."""
    if isinstance(value, str):
        return _qota._byte_size(value)
    return _whole(value, name, 1, 2**63 - 1)


def _check_tiles(tiles, plane, band, z_factor, heights_from):
    """Refuses tiles that are not this call's: another raster's grid, band, heights or z_factor
    (the heights themselves are checked block by block by the tasks, against the tiles' hashes)."""
    if not isinstance(tiles, Tiles):
        raise Error(f"tiles must be what qota.dask.tiles returns, got {type(tiles).__name__}")
    core = tiles.core
    if heights_from != "auto":
        raise Error("heights_from chooses where tiles are made from; these tiles are given (made before): leave "
                    "heights_from out, or leave out tiles")
    if ((core.height, core.width) != plane.shape
            or not np.allclose(core.geotransform, _interop.dataarray_transform(plane), rtol=0,
                               atol=1e-6 * abs(core.geotransform[1]))):
        raise Error(f"the tiles are those of another raster ({tiles.source}, {core.width} x {core.height} pixels), "
                    f"not of this {plane.shape[1]} x {plane.shape[0]} one")
    if core.band != int(band):
        raise Error(f"the tiles were made for band {core.band}, this call asks band={int(band)}")
    if core.z_factor != float(z_factor):
        raise Error(f"the tiles were made with z_factor={core.z_factor}, this call asks z_factor={float(z_factor)}: "
                    f"make them with qota.dask.tiles(da, z_factor={float(z_factor)})")


#: A block's window (the block and its overlap) is at most this many times the block's pixels:
#: chunks smaller than their halo (where each block would read hundreds of its neighbours) are
#: merged for the computation.
MOST_OVERLAP = 4.0


#: What a task holds besides the core's frame: a pixel of its given window as read, decoded to
#: float64 and copied for the core (24 bytes), and its Python objects and output block
#: (_TASK_FIXED). The core's frame of a window given whole holds less than qota shadow's tiles,
#: which also read and fill it: _FRAME_SHARE of ShadowTiles.bytes_per_window_pixel. Measured with
#: test_dask_memory's test (one task's peak in a fresh process): within 1.18, 1.32 and 1.44 times
#: the peaks of its three tasks. (_TASK_FIXED was 2 MiB while the frame kept its 1.8 MB of placement
#: buffers until its triangles were made: the 468 x 468 task's peak fell from 18.5 to 16.8 MB.)
_TASK_BYTES_PER_PIXEL = 24
_TASK_FIXED = 1 << 19
_FRAME_SHARE = 0.86


def _blocks_of(chunks):
    """The blocks (col, row, width, height) of a 2-D dask array's chunks."""
    out, row = [], 0
    for h in chunks[0]:
        col = 0
        for w in chunks[1]:
            out.append((col, row, w, h))
            col += w
        row += h
    return out


def _windows_of(core, blocks, overlap, rows, cols):
    """Each block's window: the block and its overlap, clipped to the raster, widened to whole hash
    blocks (what the task is given)."""
    west, east, north, south = overlap
    out = []
    for col, row, w, h in blocks:
        c0, r0 = max(0, col - west), max(0, row - north)
        c1, r1 = min(cols, col + w + east), min(rows, row + h + south)
        out.append(core.checkable_window((c0, r0, c1 - c0, r1 - r0)))
    return out


def _task_bytes(core, lights, blocks, overlap, rows, cols):
    """The most memory a task of these blocks takes: its given window's pixels as read and
    decoded, and the core's frame over the window it needs (planned from the heights' block
    ranges), at the core's bytes a pixel."""
    given = max(w * h for _, _, w, h in _windows_of(core, blocks, overlap, rows, cols))
    frame = core.largest_window_pixels(blocks, lights)
    per_pixel = _qota._ShadowTiles.bytes_per_window_pixel(lights)
    return int(_TASK_FIXED + given * _TASK_BYTES_PER_PIXEL + frame * _FRAME_SHARE * per_pixel)


def _blocks_for_halo(data, core, lights, void_margin, max_memory):
    """The dask array the blocks are computed on, the overlap (west, east, north, south) its blocks
    need and the memory a task takes (bytes). data is rechunked into square blocks when its chunks
    are small beside their halo (so that a call costs a small factor of qota.shadow's time whatever
    the chunks), or when a task would take more than max_memory (then blocks as large as fit)."""
    def overlap_for(width, height):
        return [side + void_margin for side in core.halo_for(width, height, lights)]

    rows, cols = data.shape
    width, height = max(data.chunks[1]), max(data.chunks[0])
    overlap = overlap_for(width, height)

    def ratio(w, h, o):
        w, h = min(w, cols), min(h, rows)
        return (min(cols, w + o[0] + o[1]) * min(rows, h + o[2] + o[3])) / (w * h)

    def task(side):
        s = min(side, rows), min(side, cols)
        blocks = _blocks_of(((s[0],) * (rows // s[0]) + ((rows % s[0],) if rows % s[0] else ()),
                             (s[1],) * (cols // s[1]) + ((cols % s[1],) if cols % s[1] else ())))
        return _task_bytes(core, lights, blocks, overlap_for(s[1], s[0]), rows, cols)

    if ratio(width, height, overlap) > MOST_OVERLAP:
        side = max(width, height, 64)
        while side < max(rows, cols):
            side = min(2 * side, max(rows, cols))
            if ratio(side, side, overlap_for(side, side)) <= MOST_OVERLAP:
                break
        data = data.rechunk((min(side, rows), min(side, cols)))
        width, height = max(data.chunks[1]), max(data.chunks[0])
        overlap = overlap_for(width, height)
    need = _task_bytes(core, lights, _blocks_of(data.chunks), overlap, rows, cols)
    if max_memory is None or need <= max_memory:
        return data, overlap, need
    lo, hi = 0, max(width, height)  # the largest square side (a multiple of 16) whose task fits
    while hi - lo > 16:
        mid = (lo + hi) // 32 * 16
        lo, hi = (mid, hi) if task(mid) <= max_memory else (lo, mid)
    if lo == 0:
        raise Error(f"max_memory={max_memory}: even blocks of 16 pixels take {task(16)} bytes a task at this light "
                    f"(the halo their shadows need); give more")
    data = data.rechunk((min(lo, rows), min(lo, cols)))
    return data, overlap_for(min(lo, cols), min(lo, rows)), task(lo)


# --- writing -----------------------------------------------------------------------------------

def _staged(path):
    """A fresh path beside `path` (the same file system, so that moving it into place is a rename)
    that no other writer uses."""
    folder, name = os.path.split(os.path.abspath(path))
    return os.path.join(folder, f".qota-partial-{os.getpid()}-{uuid.uuid4().hex[:12]}-{name}")


def _remove(path):
    if os.path.isdir(path) and not os.path.islink(path):
        shutil.rmtree(path, ignore_errors=True)
    elif os.path.lexists(path):
        os.remove(path)


def _computed(result):
    """The result with every block computed (held where it was computed: the workers' memory on a
    cluster, 1 byte a pixel for masks, 4 for hours), so that a failing block fails before anything
    is written, and no block still running writes after a failure was reported."""
    from dask import persist

    (done,) = persist(result)  # Dask's local schedulers: computed here, raising the first failure
    try:
        from distributed import futures_of, wait
    except ImportError:
        return done
    futures = futures_of(done)
    if futures:
        wait(futures)  # every block finished, failed or not: none is still running
        for future in futures:
            if future.status == "error":
                future.result()  # raises the block's own error
    return done


def _check_lossless(profile):
    """Refuses creation options that would change the values written (as qota shadow does)."""
    options = {str(k).lower(): str(v).lower() for k, v in profile.items()}
    compress = options.get("compress", "")
    lossy = (compress == "jpeg" or (compress == "webp" and options.get("webp_lossless") != "true"
                                    and options.get("webp_lossless") != "yes")
             or (compress.startswith("lerc") and float(options.get("max_z_error", 0) or 0) != 0)
             or options.get("jxl_lossless") in ("no", "false") or options.get("pixeltype") == "signedbyte")
    if "nbits" in options and options["nbits"] not in ("8", "32"):
        lossy = True
    if lossy:
        shown = ", ".join(f"{k}={v!r}" for k, v in profile.items())
        raise Error(f"to_geotiff({shown}): the values written would not be the ones computed; give lossless "
                    f"options (compress='deflate', 'lzw' or 'zstd'), or none")


def to_geotiff(result, path, *, lock=None, **profile):
    """Writes a (lazy) result as a tiled GeoTIFF (rioxarray's to_raster with tiled=True), with the
    source's geotransform as the result keeps it. Whole or not at all: every block is computed
    first (held in the workers' memory: 1 byte a pixel for masks, 4 for hours), then the file is
    written under a staging name beside `path` and renamed into place; a failed block leaves
    `path` as it was. lock: one
    writer at a time across the workers; by default a distributed.Lock when a distributed Client
    is active (the folder must then be on a file system every worker sees), else a threading
    lock. profile: creation options (compress="deflate", blockxsize=..., ...)."""
    path = os.fspath(path)
    _check_lossless(profile)
    result = _computed(result)
    staged = _staged(path)
    if lock is None:
        lock = _writer_lock(staged)
    profile.setdefault("recalc_transform", False)
    try:
        result.rio.to_raster(staged, tiled=True, lock=lock, compute=True, **profile)
        os.replace(staged, path)
    finally:
        for leftover in (staged, staged + ".aux.xml"):
            if os.path.lexists(leftover):
                _remove(leftover)


def to_zarr(result, path, *, name=None, **kwargs):
    """Writes a (lazy) result as a Zarr store (xarray's to_zarr of a dataset with one variable,
    `name`: the result's own name by default, "shadow" or "sunlight_hours"), whole or not at all:
    every block computed first (as to_geotiff), written under a staging name beside `path`, then
    moved into place (a store already there is replaced only then). kwargs: to_zarr's
    (consolidated=..., encoding=...)."""
    path = os.fspath(path)
    result = _computed(result)
    staged = _staged(path)
    try:
        result.to_dataset(name=name or result.name or "data").to_zarr(staged, mode="w-", **kwargs)
        old = None
        if os.path.lexists(path):
            old = _staged(path)
            os.replace(path, old)
        try:
            os.replace(staged, path)
        except BaseException:
            if old is not None:
                os.replace(old, path)
            raise
        if old is not None:
            _remove(old)
    finally:
        if os.path.lexists(staged):
            _remove(staged)


def _writer_lock(path):
    try:
        from distributed import Lock, default_client
        client = default_client()
    except (ImportError, ValueError):  # no distributed, or no client: Dask's local schedulers
        return threading.Lock()
    return Lock("qota-geotiff-" + os.path.abspath(path), client=client)


# --- points ------------------------------------------------------------------------------------

def _file_identity(path):
    """What tells one version of a raster from another: the device, inode, size and modification
    time of every local file GDAL reads for it (the file, a VRT's sources, its sidecars), sorted
    by name; None when none is a local file (GDAL's virtual paths and names)."""
    path = os.fspath(path)
    files = {path, *_qota._raster_files(path)}
    identity = []
    for name in sorted(files):
        try:
            st = os.stat(name)
        except (OSError, ValueError):
            continue
        identity.append((name, st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns))
    return tuple(identity) or None


def _sample_source(path, band, resampling):
    """What one sample() call's tasks are given: the raster, a token of the call, so that a later
    call (the file rewritten in between, a VRT's member replaced) opens the raster afresh instead
    of answering from the tiles an earlier call cached, and the file's identity then, which each
    process checks as it reads the raster."""
    return (path, band, resampling, uuid.uuid4().hex, _file_identity(path))


def _unchanged(path, identity, call):
    """Refuses a raster that changed after the call that set up the computation: its tasks would
    answer from two versions, or from the old one's cached tiles."""
    now = _file_identity(path)
    if now != identity:
        before, after = ({f[0]: f for f in i or ()} for i in (identity, now))
        changed = sorted(n for n in before.keys() | after.keys() if before.get(n) != after.get(n))
        which = "" if changed in ([], [os.fspath(path)]) else f" ({', '.join(changed)})"
        raise Error(f"{path}{which} changed after qota.dask.{call} was called (it was rewritten or replaced); "
                    f"call qota.dask.{call} again to use the new file")


#: Each process's samplers: for each raster (path, band, resampling), the latest sample() call's,
#: at most 8 rasters (a sampler holds up to 128 MiB of tiles).
_samplers = {}
_samplers_lock = threading.Lock()


def _sampler(source):
    """The sampler of a raster and a sample() call in this process: its tile cache serves every
    task of the call there, and a later call's replaces it."""
    path, band, resampling, call, identity = source
    key = (path, band, resampling)
    with _samplers_lock:
        held = _samplers.get(key)
        if held is not None and held[0] == call:
            return held[1]
    sampler = _qota._RasterSampler(path, band, resampling)
    _unchanged(path, identity, "sample")
    with _samplers_lock:
        _samplers.pop(key, None)
        _samplers[key] = (call, sampler)  # (the newest last)
        while len(_samplers) > 8:
            _samplers.pop(next(iter(_samplers)))
    return sampler


def _sample_xy(source, x, y):
    heights = _sampler(source).heights(np.ascontiguousarray(x, dtype=np.float64),
                                       np.ascontiguousarray(y, dtype=np.float64))
    _unchanged(source[0], source[4], "sample")  # (the tiles this batch read are of that version)
    return heights


def _sample_frame(frame, source, x, y, name):
    import pandas as pd

    return pd.Series(_sample_xy(source, frame[x].to_numpy(), frame[y].to_numpy()), index=frame.index, name=name)


def _sample_geodataframe(frame, source, field):
    from . import sample as sample_points

    path, band, resampling, _, identity = source
    _unchanged(path, identity, "sample")
    sampled = sample_points(path, frame, band=band, resampling=resampling, field=field)
    _unchanged(path, identity, "sample")  # (the partition's heights are of that version)
    return sampled


def _sample_rows(points, source):
    return _sample_xy(source, points[:, 0], points[:, 1])


def _block_keys(frame, x, y, inverse, size, across):
    """The raster block of each point (blocks of size x size pixels, numbered by rows; inverse:
    GDAL's inverse geotransform), for grouping points by where they read; points that are not
    finite share key -1."""
    px, py = frame[x].to_numpy(dtype=np.float64), frame[y].to_numpy(dtype=np.float64)
    col = inverse[0] + inverse[1] * px + inverse[2] * py
    row = inverse[3] + inverse[4] * px + inverse[5] * py
    keys = np.full(len(px), -1, dtype=np.int64)
    ok = np.isfinite(col) & np.isfinite(row)
    keys[ok] = np.floor(row[ok] / size) * across + np.floor(col[ok] / size)
    return keys


def sample(source, points, *, band=1, x="x", y="y", by_block=False, block=1024, resampling="triangle",
           field="height", chunksize=100_000):
    """Heights of a raster under points, lazily: qota.sample(source, x, y, resampling=...), bit
    for bit (with "triangle", Terrain.from_raster(source).heights(x, y)), NaN where there is no
    terrain (a hole, off the raster).

    source: a raster path (or GDAL name) that every worker can open.
    points: a dask DataFrame with columns `x` and `y` (the raster's CRS), giving a dask Series
        "height" with the same index and partitions; or a dask array of shape (n, 2), giving a
        dask array (n,) on the same row chunks. Each partition is answered in one batch by its
        process's sampler, which groups the batch's points by raster tile. Or GeoDataFrames of
        points: a dask DataFrame whose partitions are geopandas GeoDataFrames
        (`dask.dataframe.from_pandas(gdf, npartitions=...)`, or a dask-geopandas frame), giving
        the same partitions with a column `field` of heights added, each partition's points taken
        in its own CRS, as qota.sample(source, gdf) does; a geopandas GeoDataFrame itself is split
        into partitions of `chunksize` rows first.
    by_block: for a DataFrame: shuffle the points first so that each partition holds the points
        of whole raster blocks of `block` x `block` pixels (where many random points fall on a
        raster larger than a worker's tile cache, each tile is then built once, not once a
        partition), then put the heights back in the input's partitions and order, by each
        point's place there (whatever its index: repeated, unsorted or not numbers). Costs two
        shuffles of the points.
    """
    path = _local_file(source)
    band, block = _whole(band, "band"), _whole(block, "block")
    from . import RESAMPLINGS
    if resampling not in RESAMPLINGS:
        raise Error(f"resampling must be one of {', '.join(RESAMPLINGS)}, got {resampling!r}")
    source = _sample_source(path, band, resampling)  # (before the description: a change after it is then seen)
    description = _qota._describe_raster(path, band)  # refused here, on the client, if unreadable
    from . import _is_geodataframe
    if _is_geodataframe(points) and not hasattr(points, "map_partitions"):
        import dask.dataframe as dd
        points = dd.from_pandas(points, chunksize=_whole(chunksize, "chunksize"))
    if hasattr(points, "map_partitions") and _is_geodataframe(getattr(points, "_meta", None)):
        if by_block:
            raise Error("by_block takes a dask DataFrame of x, y columns; GeoDataFrames are answered in their own partitions")
        if field in points.columns:
            raise Error(f"the GeoDataFrame already has a column {field!r}; name the heights' column with field=")
        meta = points._meta.assign(**{field: np.zeros(0, dtype=np.float64)})
        return points.map_partitions(_sample_geodataframe, source, field, meta=meta)
    if hasattr(points, "map_partitions") and hasattr(points, "columns"):
        for column in (x, y):
            if column not in points.columns:
                raise Error(f"the points have no column {column!r} (columns: {', '.join(map(str, points.columns))})")
        if by_block:
            return _sample_by_block(source, points, x, y, description, int(block))
        return points.map_partitions(_sample_frame, source, x, y, "height", meta=("height", "f8"))
    if _is_dask(points) and points.ndim == 2 and points.shape[1] == 2:
        if by_block:
            raise Error("by_block takes a dask DataFrame of points (a dask array is answered in its own chunks)")
        if len(points.chunks[1]) > 1:
            points = points.rechunk({1: 2})
        return points.map_blocks(_sample_rows, source, drop_axis=1, dtype=np.float64)
    raise Error(f"points must be a dask DataFrame with columns {x!r} and {y!r}, a dask array of shape (n, 2), "
                f"or GeoDataFrames of points; got {type(points).__name__}")


#: A point's place in its input: partition number * _PLACE + its row within the partition.
_PLACE = 1 << 40


def _with_places(frame, x, y, partition_info=None):
    """The points' x, y and their place in the input (partition, row), which the heights are put
    back by: the index cannot do it (its values may repeat, be unsorted or not numbers)."""
    import pandas as pd

    number = partition_info["number"] if partition_info else 0
    return pd.DataFrame({x: frame[x].to_numpy(), y: frame[y].to_numpy(),
                         "_qota_place": np.arange(len(frame), dtype=np.int64) + number * _PLACE})


def _placed_heights(frame, source, x, y):
    import pandas as pd

    return pd.DataFrame({"_qota_place": frame["_qota_place"].to_numpy(),
                         "height": _sample_xy(source, frame[x].to_numpy(), frame[y].to_numpy())})


def _in_input_order(heights, points):
    """The heights of one input partition (sorted by place), on the partition's own index."""
    import pandas as pd

    values = heights["height"].to_numpy()
    if len(values) != len(points):
        raise Error(f"{len(values)} heights came back for a partition of {len(points)} points")
    return pd.Series(values, index=points.index, name="height")


def _sample_by_block(source, points, x, y, description, block):
    if block < 1:
        raise Error(f"block must be a number of pixels (1 or more), got {block}")
    import dask.dataframe as dd

    across = -(-description["width"] // block)
    n = points.npartitions
    placed = points.map_partitions(_with_places, x, y, meta={x: "f8", y: "f8", "_qota_place": "i8"},
                                   enforce_metadata=False)
    keys = placed.map_partitions(_block_keys, x, y, description["inverse_geotransform"], block, across,
                                 meta=("_qota_block", "i8"))
    heights = placed.assign(_qota_block=keys).shuffle("_qota_block") \
        .map_partitions(_placed_heights, source, x, y, meta={"_qota_place": "i8", "height": "f8"})
    # Back in the input's partitions, by place: partition k holds the places [k _PLACE, (k + 1) _PLACE).
    divisions = [k * _PLACE for k in range(n)] + [n * _PLACE - 1]
    back = heights.set_index("_qota_place", divisions=divisions, sorted=False)
    return dd.map_partitions(_in_input_order, back, points, meta=("height", "f8"), align_dataframes=False)


#: The value of viewsheds' pixels that have no data.
VIEWSHED_NODATA = np.iinfo(np.uint32).max


def _viewshed_counts(path, identity, xs, ys, heights, target_height, max_distance, band, flat, height_ref):
    _unchanged(path, identity, "viewsheds")
    counts = _qota._cumulative(path, xs, ys, heights, target_height, max_distance, band, flat, height_ref)
    _unchanged(path, identity, "viewsheds")  # (the counts are of the raster the call described)
    return counts


def viewsheds(source, observers, *, observer_height=2.0, target_height=0.0, max_distance=0.0, band=1, flat=False,
              height_ref=None, per_task=16):
    """How many of `observers` see each pixel of a raster, lazily, as `qota viewshed --observers`
    counts them (the exact rule of qota.viewshed): a dask array (rows, columns) of uint32 counts,
    VIEWSHED_NODATA where the raster has no data.

    source: a raster path (or GDAL name) that every worker can open.
    observers: (n, 2) x, y in the raster's CRS, or (n, 3) with each observer's height above the
        surface (metres; else observer_height).
    per_task: observers a task looks from; each task places and indexes the whole raster once
        (the memory of `qota viewshed` on it), the tasks' counts are summed.
    """
    import dask
    import dask.array as da

    path = _local_file(source)
    band, per_task = _whole(band, "band"), _whole(per_task, "per_task")
    identity = _file_identity(path)  # (before the description: a change after it is then seen)
    description = _qota._describe_raster(path, band)  # refused here, on the client, if unreadable
    points = np.asarray(observers, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] not in (2, 3) or len(points) == 0:
        raise Error(f"observers must be an (n, 2) or (n, 3) array of x, y [, height] with n > 0; got shape "
                    f"{points.shape}")
    height = _height(observer_height, "observer_height")
    heights = points[:, 2].copy() if points.shape[1] == 3 else np.full(len(points), height)
    target, distance = _height(target_height, "target_height"), _number(max_distance, "max_distance")
    # Checked here, on the client, before any task runs: a bad observer would fail its task only
    # once the graph is computed (as qota.viewshed checks them).
    unplaced = ~np.isfinite(points[:, :2]).all(axis=1)
    if unplaced.any():
        i = int(np.argmax(unplaced))
        raise Error(f"observers[{i}]: x, y must be finite, got {points[i, 0]!r}, {points[i, 1]!r}")
    wrong = ~((heights >= 0) & (heights <= MAX_HEIGHT))
    if wrong.any():
        i = int(np.argmax(wrong))
        raise Error(f"observers[{i}]: the height must be a number of metres from 0 to 1e9 (beyond any terrain), "
                    f"got {heights[i]!r}")
    if not distance >= 0:
        raise Error(f"max_distance must be a number of metres, 0 or more, got {distance!r}")
    reference = "" if height_ref is None else os.fspath(height_ref)
    parts = []
    for first in range(0, len(points), per_task):
        group = slice(first, first + per_task)
        counts = dask.delayed(_viewshed_counts, pure=True)(path, identity, points[group, 0].copy(),
                                                          points[group, 1].copy(), heights[group], target, distance,
                                                          band, bool(flat), reference)
        parts.append(counts)
    rows, cols = description["height"], description["width"]
    total = da.stack([da.from_delayed(p, shape=(rows, cols), dtype=np.int64) for p in parts]).sum(axis=0)
    return da.where(total < 0, VIEWSHED_NODATA, total).astype(np.uint32)

