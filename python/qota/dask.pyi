# Types of qota.dask. xarray, dask and pandas are optional at import time, so their types are
# named as Any here: the DataArrays, dask DataFrames and Series these functions take and return.
from dataclasses import dataclass
from os import PathLike
from typing import Any, Literal

VOID_MARGIN: int
MOST_OVERLAP: float

_Path = str | PathLike[str]
_Size = int | str

@dataclass(frozen=True)
class Tiles:
    core: object
    heights_from: str
    source: str

def tiles(da: Any, *, band: int = 1, z_factor: float = 1.0,
          heights_from: Literal["auto", "file", "array"] = "auto") -> Tiles: ...
def shadow(da: Any, azimuth: float | None = None, altitude: float | None = None, *, time: str | None = None,
           tz: str | None = None, hours: tuple[float, float, float] | None = None, band: int = 1,
           z_factor: float = 1.0, void_margin: int = ..., heights_from: Literal["auto", "file", "array"] = "auto",
           tiles: Tiles | None = None, threads: int = 1, max_memory: _Size | None = None) -> Any: ...
def to_geotiff(result: Any, path: _Path, *, lock: Any = None, **profile: Any) -> None: ...
def to_zarr(result: Any, path: _Path, *, name: str | None = None, **kwargs: Any) -> None: ...
def sample(source: _Path, points: Any, *, band: int = 1, x: str = "x", y: str = "y", by_block: bool = False,
           block: int = 1024,
           resampling: Literal["triangle", "nearest", "bilinear", "cubic"] = "triangle") -> Any: ...
VIEWSHED_NODATA: int
def viewsheds(source: _Path, observers: Any, *, observer_height: float = 2.0, target_height: float = 0.0,
              max_distance: float = 0.0, band: int = 1, flat: bool = False, height_ref: _Path | None = None,
              per_task: int = 16) -> Any: ...
