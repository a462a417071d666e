"""A typed use of qota, checked by mypy --strict against the package's stubs (scripts/python-test.sh)
and run by the tests (test_typed_example.py): what the stubs promise is what the package does."""
from __future__ import annotations

import numpy as np
import numpy.typing as npt

import qota


def floor_and_ceiling(terrain: qota.Terrain, x: npt.ArrayLike, y: npt.ArrayLike,
                      z: npt.ArrayLike) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    below: npt.NDArray[np.float64] = terrain.below(x, y, z)
    above: npt.NDArray[np.float64] = terrain.above(x, y, z)
    return below, above


def top_polygons(terrain: qota.Terrain, x: npt.ArrayLike, y: npt.ArrayLike) -> npt.NDArray[np.int64]:
    hit: qota.Hits = terrain.hits(x, y, normals=False)
    assert hit.normal is None
    return hit.polygon


def slopes(terrain: qota.Terrain, x: npt.ArrayLike, y: npt.ArrayLike) -> npt.NDArray[np.float64]:
    normal = terrain.hits(x, y).normal
    assert normal is not None
    up: npt.NDArray[np.float64] = np.degrees(np.arccos(np.clip(normal[..., 2], -1, 1)))
    return up


def ramp() -> qota.Terrain:
    heights = np.add.outer(np.arange(4.0), np.arange(5.0))
    terrain = qota.Terrain.from_array(heights, (0.0, 1.0, 0.0, 4.0, 0.0, -1.0), crs="EPSG:32610")
    names: tuple[str, ...] = qota.MAPPINGS
    assert terrain.mapping in names
    return terrain


def run() -> dict[str, float]:
    terrain = ramp()
    lo, hi = floor_and_ceiling(terrain, [1.5], [2.5], [100.0])
    return {"floor": float(lo[0]), "ceiling": float(hi[0]), "polygon": float(top_polygons(terrain, 1.5, 2.5)),
            "slope": float(slopes(terrain, 1.5, 2.5))}
