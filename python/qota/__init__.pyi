from os import PathLike
from typing import Any, Literal, NamedTuple

import numpy as np
import numpy.typing as npt

__version__: str

class Error(ValueError): ...

_Coords = npt.ArrayLike
_Path = str | PathLike[str]
_Mapping = Literal["cartesian", "spherical", "cylindrical", "geodetic", "enu"]
_Origin = tuple[float, float] | tuple[float, float, float]
# A raster: a path, an open rasterio dataset, or an xarray.DataArray with rioxarray's accessor
# (rasterio and xarray are optional, so their types are not named here).
_Raster = _Path | Any

MAPPINGS: tuple[str, ...]

class Hits(NamedTuple):
    height: npt.NDArray[np.float64]
    polygon: npt.NDArray[np.int64]
    normal: npt.NDArray[np.float64] | None

_Side = Literal["top", "below", "above"]
_Heights = npt.NDArray[np.float64]

class Terrain:
    @classmethod
    def from_raster(cls, path: _Raster, band: int = 1, mapping: _Mapping = "cartesian", radius: float | None = None,
                    length: float | None = None, *, height_ref: _Path | None = None,
                    origin: _Origin | None = None) -> Terrain: ...
    @classmethod
    def from_xarray(cls, da: Any, band: int = 1, mapping: _Mapping = "cartesian", radius: float | None = None,
                    length: float | None = None, *, height_ref: _Path | None = None,
                    origin: _Origin | None = None) -> Terrain: ...
    @classmethod
    def from_array(cls, heights: npt.ArrayLike, transform: Any, nodata: float | None = None, *, crs: Any = None,
                   unit: str | None = None, mapping: _Mapping = "cartesian", radius: float | None = None,
                   length: float | None = None, height_ref: _Path | None = None,
                   origin: _Origin | None = None) -> Terrain: ...
    @classmethod
    def from_mesh(cls, vertices: npt.ArrayLike, triangles: npt.ArrayLike, *,
                  mapping: _Mapping = "cartesian",
                  origin: _Origin | None = None) -> Terrain: ...
    @classmethod
    def load(cls, path: _Path) -> Terrain: ...
    def save(self, path: _Path) -> None: ...
    @property
    def mapping(self) -> str: ...
    @property
    def crs(self) -> str | None: ...
    @property
    def height_ref(self) -> str | None: ...
    # One type per call: heights as arrays; polygon ids and normals through hits(). (The 0.2 flags
    # polygons=/normals= still run, returning a tuple with a DeprecationWarning; not typed here.)
    def hits(self, x: _Coords, y: _Coords, z: _Coords | None = None, *, side: _Side = "top",
             normals: bool = True) -> Hits: ...
    def heights(self, x: _Coords, y: _Coords) -> _Heights: ...
    def below(self, x: _Coords, y: _Coords, z: _Coords) -> _Heights: ...
    def above(self, x: _Coords, y: _Coords, z: _Coords) -> _Heights: ...
    def bracket(self, x: _Coords, y: _Coords, z: _Coords) -> tuple[_Heights, _Heights]: ...
    def all(self, x: float, y: float) -> list[tuple[float, int, tuple[float, float, float]]]: ...
    def stats(self) -> dict[str, int]: ...

# A numpy array for a file (float32 with hours); an xarray.DataArray for a DataArray or a rasterio
# dataset.
def shadow(dem_path: _Raster, azimuth: float | None = None, altitude: float | None = None, *, time: str | None = None,
           tz: str | None = None, hours: tuple[float, float, float] | None = None, band: int = 1,
           z_factor: float = 1.0, output: _Path | None = None, height_ref: _Path | None = None,
           sun_vector: tuple[float, float, float] | None = None, sun_vector_body: tuple[float, float, float] | None = None,
           subsolar: tuple[float, float] | None = None,
           flat: bool = False, png: _Path | None = None) -> npt.NDArray[np.uint8] | npt.NDArray[np.float32] | Any: ...
# uint8: 255 visible, 0 not, 128 nodata, 64 out of range; a numpy array for a file, an
# xarray.DataArray for a DataArray or a rasterio dataset.
def viewshed(dem: _Raster, observer: tuple[float, float], *, observer_height: float = 2.0,
             target_height: float = 0.0, max_distance: float = 0.0, srs: str | None = None, band: int = 1,
             flat: bool = False, height_ref: _Path | None = None, refraction: float = 0.0,
             output: _Path | None = None) -> npt.NDArray[np.uint8] | Any: ...
RESAMPLINGS: tuple[str, ...]
# float64 heights, NaN where there are none; the shape of x and y broadcast together.
# With x a geopandas GeoDataFrame of points and no y: a copy of it with a column of heights.
def sample(dem: _Raster, x: _Coords | Any, y: _Coords | None = None, *, band: int = 1,
           resampling: Literal["triangle", "nearest", "bilinear", "cubic"] = "triangle",
           srs: str | None = None, field: str = "height") -> _Heights | Any: ...
def sun_position(time: str, lon: float, lat: float, *, tz: str | None = None) -> tuple[float, float]: ...
