// Where a terrain comes from: a tree file (qota build's output), or a raster or mesh file built
// in the mapping asked for. One place, so that the tools, the C++ Terrain (terrain_face.hpp) and
// Python accept the same sources.
#pragma once

#include <array>
#include <optional>
#include <string>

#include "qota/treefile.hpp"

namespace qota {

struct SourceOptions {
  std::string source = {};  ///< a .qota tree file, a raster, or a mesh file
  /// cartesian | spherical | geodetic | cylindrical | enu; empty: a tree file's own, else cartesian
  std::string mapping = {};
  double radius = 0;         ///< spherical: planet radius; cylindrical: station radius
  double length = 0;         ///< cylindrical: station length
  int band = 0;              ///< raster band (1-based); 0: the raster's only band
  bool heightsOnly = false;  ///< only heights at points (sample): no quadtree on a grid
  /// geodetic, enu: what the raster's heights are over (qota/geoid.hpp; "": its own, else assumed)
  std::string heightRef = {};
  /// enu: the frame's origin (latitude, longitude degrees, height metres over the ellipsoid);
  /// none: the raster's centre at height 0 (a mesh: the centre of its box, at its height).
  std::optional<std::array<double, 3>> origin = {};
  IndexOptions index = {};  ///< the index's options: the quadtree's Maxpoly and Maxdepth, the grid path
  /// a raster's voids filled first (DemOptions::fillVoids: GDAL's fill-nodata, pixels searched); 0: holes
  double fillVoids = 0;
};

/// A tree file is loaded as it is (its own mapping; asking for another is an error). A raster
/// becomes: cartesian: the DEM as a map (loadDem); spherical: a planet (loadPlanet); geodetic: the
/// DEM on its ellipsoid (loadOnEllipsoid); cylindrical: the relief of a station around the z axis
/// (stationMesh). A file GDAL cannot open as a raster is read as a mesh (loadMeshFile: OBJ, PLY,
/// glTF, STL, ... or 3D polygons in any vector format) in world coordinates: cartesian with
/// gravity -Z, or the mapping's default frame (sphere or cylinder about the origin and z axis,
/// WGS84 with ECEF coordinates). A raster in longitude/latitude is accepted in the cartesian
/// mapping (x, y in degrees): the tools that take this index ask for heights at points, which
/// the lon/lat grid gives exactly. Throws qota::Error.
TreeFile openIndex(const SourceOptions& options);

/// Each mapping parameter only where the mapping takes it (the registry's entry says which):
/// --radius, --length, --origin and --height-ref given to a mapping that takes none are refused by
/// name (qota::Error). openIndex checks it; a tool that reads a source another way calls it.
void requireMappingOptions(const SourceOptions& options);

/// A mesh in world coordinates built in a mapping's default frame, as openIndex builds a mesh
/// file: cartesian with gravity -Z about cartesianOrigin; a sphere or cylinder about the origin
/// and z axis; the WGS84 ellipsoid in ECEF metres; enu at `origin` (latitude, longitude degrees,
/// height), by default the ellipsoid point under the centre of the vertices' box. Throws
/// qota::Error for an unknown mapping, or an origin given to another mapping.
AnyIndex meshIndex(const Mesh& mesh, const std::string& mapping, const Eigen::Vector3d& cartesianOrigin,
                   const std::optional<std::array<double, 3>>& origin = {}, const IndexOptions& terrain = {});

/// The memory a job on this source was estimated to peak at (qota/memory_budget.hpp), as the
/// loaders estimate it before reading a raster: the process, the terrain and its index.
std::uint64_t estimatedPeakBytes(const TreeFile& tree, const SourceOptions& options);

/// Whether GDAL opens the file as a raster (else it is read as a mesh or a tree file).
bool isRaster(const std::string& path);
/// Throws qota::Error "PATH: cannot open: no such file" for a local file that is not there.
void requireSource(const std::string& path);

/// The mapping name of an index ("cartesian", ...).
const char* mappingNameOf(const AnyIndex& index);

}  // namespace qota
