// Where the tools get their index: a tree file (qota build's output), or a raster or mesh file
// built in the mapping asked for. One place, so that `sample`, `info` and `build` accept the
// same sources.
#pragma once

#include <string>

#include "qota/treefile.hpp"

namespace qota::tools {

struct SourceOptions {
  std::string source;                 // a .qota tree file, a raster, or a mesh file
  // cartesian | spherical | geodetic | cylindrical; empty: a tree file's own, else cartesian
  std::string mapping;
  double radius = 0;                  // spherical: planet radius; cylindrical: station radius
  double length = 0;                  // cylindrical: station length
  int band = 0;                       // raster band (1-based); 0: the raster's only band
  bool heightsOnly = false;           // only heights at points (sample): no quadtree on a grid
  // geodetic: what the raster's heights are over (qota/geoid.hpp; "": its own, else assumed)
  std::string heightRef = {};
  IndexOptions terrain;
};

// A tree file is loaded as it is (its own mapping; asking for another is an error). A raster
// becomes: cartesian: the DEM as a map (loadDem); spherical: a planet (loadPlanet); geodetic: the
// DEM on its ellipsoid (loadOnEllipsoid); cylindrical: the relief of a station around the z axis
// (stationMesh). A file GDAL cannot open as a raster is read as a mesh (loadMeshFile: OBJ, PLY,
// glTF, STL, ... or 3D polygons in any vector format) in world coordinates: cartesian with
// gravity -Z, or the mapping's default frame (sphere or cylinder about the origin and z axis,
// WGS84 with ECEF coordinates). A raster in longitude/latitude is accepted in the cartesian
// mapping (x, y in degrees): the tools that take this index ask for heights at points, which
// the lon/lat grid gives exactly. Throws qota::Error.
TreeFile openIndex(const SourceOptions& options);

// The memory a job on this source was estimated to peak at (qota/memory_budget.hpp), as the
// loaders estimate it before reading a raster: the process, the terrain and its index.
std::uint64_t estimatedPeakBytes(const TreeFile& tree, const SourceOptions& options);

// Whether GDAL opens the file as a raster (else it is read as a mesh or a tree file).
bool isRaster(const std::string& path);
// Throws qota::Error "PATH: cannot open: no such file" for a local file that is not there.
void requireSource(const std::string& path);

// The mapping name of an index ("cartesian", ...).
const char* mappingNameOf(const AnyIndex& index);

}  // namespace qota::tools
