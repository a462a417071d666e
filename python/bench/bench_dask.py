"""qota.dask.shadow on a LocalCluster of 1 and 2 worker processes (one thread each) against
qota.shadow of the whole raster in one process (the baseline, on every core; also shown pinned
to one core).

    build-venv/bin/python python/bench/bench_dask.py [--size 4000] [--chunks 1000] [--runs 3]

The raster: the Rainier tile mirrored into a mosaic of size x size pixels (lon/lat, on the
ellipsoid; mirrored so the relief runs on across the seams), written once to a tiled GeoTIFF in
the temporary folder. Each configuration runs `runs` times; the table gives the median and the
spread (min to max: the run-to-run noise), the ratio to the baseline's median, and checks every
result equal to the baseline's pixel for pixel. Dask's times include everything a user waits
for: the client's pass over the heights (also shown alone), the graph, the blocks, and the mask
gathered on the client. Prints the halo of a block and the overlap's cost, ((b + overlap) / b)^2.
"""
import argparse
import os
import statistics
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
import rasterio
import rioxarray

import qota
import qota.dask


def mosaic(size):
    """The Rainier tile mirrored to size x size pixels, in a GeoTIFF of 512-pixel blocks."""
    path = Path(tempfile.gettempdir()) / f"qota_bench_dask_{size}.tif"
    if path.exists():
        return path
    rainier = Path(__file__).resolve().parents[2] / "data" / "mt_rainier_90m.tif"
    with rasterio.open(rainier) as ds:
        z = ds.read(1)
        profile = ds.profile
    tile = np.block([[z, z[:, ::-1]], [z[::-1, :], z[::-1, ::-1]]])
    reps = -(-size // tile.shape[0])
    heights = np.tile(tile, (reps, reps))[:size, :size]
    profile.update(width=size, height=size, tiled=True, blockxsize=512, blockysize=512, compress="deflate")
    with rasterio.open(path, "w", **profile) as out:
        out.write(heights, 1)
    return path


def timed(f, runs):
    times, out = [], None
    for _ in range(runs):
        start = time.perf_counter()
        out = f()
        times.append(time.perf_counter() - start)
    return times, out


def pinned_shadow(path, sun, runs):
    """qota.shadow's times on one core (this process pinned to it)."""
    os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
    return timed(lambda: qota.shadow(path, **sun), runs)[0]


def row(name, times, base):
    median = statistics.median(times)
    ratio = f"{median / base:5.2f}x" if base else "   1  "
    print(f"| {name:<28} | {median:7.2f} s | {min(times):6.2f} - {max(times):6.2f} s | {ratio} |")
    return median


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--size", type=int, default=4000)
    p.add_argument("--chunks", type=int, default=1000)
    p.add_argument("--runs", type=int, default=3)
    p.add_argument("--azimuth", type=float, default=135)
    p.add_argument("--altitude", type=float, default=20)
    a = p.parse_args()
    from distributed import Client, LocalCluster

    path = mosaic(a.size)
    sun = dict(azimuth=a.azimuth, altitude=a.altitude)
    dem = rioxarray.open_rasterio(path, chunks=a.chunks)
    tiles = qota.dask.tiles(dem).core
    halo = tiles.halo_for(a.chunks, a.chunks, [tiles.toward_sun(a.azimuth, a.altitude)])
    grown = [(a.chunks + h[0] + h[1] + 2 * qota.dask.VOID_MARGIN) / a.chunks for h in ((halo[0], halo[1]), (halo[2], halo[3]))]
    print(f"{a.size} x {a.size} pixels ({path}), blocks of {a.chunks}, sun {a.azimuth}/{a.altitude}, "
          f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f} (other work on the machine: noise)")
    print(f"halo (west, east, north, south): {halo} pixels, + {qota.dask.VOID_MARGIN} for voids; "
          f"pixels read per pixel computed at most {grown[0] * grown[1]:.2f}")
    print()
    print(f"| {'run':<28} | median    | spread (min - max) | ratio |")
    print("|---|---|---|---|")
    times, want = timed(lambda: qota.shadow(path, **sun), a.runs)
    base = row("qota.shadow, one process", times, None)
    with ProcessPoolExecutor(1) as pool:
        row("qota.shadow, one core", pool.submit(pinned_shadow, path, sun, a.runs).result(), base)
    times, _ = timed(lambda: qota.dask.tiles(dem), a.runs)
    row("client's pass (height range)", times, base)
    for workers in (1, 2):
        with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
                Client(cluster):
            times, got = timed(lambda: qota.dask.shadow(dem, **sun).values[0], a.runs)
            assert np.array_equal(got, want), "the blocks differ from the whole raster's mask"
            row(f"qota.dask, {workers} worker{'s' if workers > 1 else ''}", times, base)
    print(f"\nload average at the end: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
