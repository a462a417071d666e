#include "index_source.hpp"

#include <gdal_priv.h>

#include <algorithm>
#include <filesystem>
#include <memory>

#include "gdal_errors.hpp"
#include "qota/dem.hpp"
#include "qota/error.hpp"
#include "qota/globe.hpp"
#include "qota/mesh_io.hpp"

namespace qota::tools {

bool isRaster(const std::string& path) {
  ensureGdalRegistered();
  const detail::QuietGdalErrors quiet;  // a mesh file is not an error here
  const std::unique_ptr<GDALDataset> ds(
      static_cast<GDALDataset*>(GDALOpenEx(path.c_str(), GDAL_OF_RASTER, nullptr, nullptr, nullptr)));
  return ds != nullptr;
}

namespace {

TreeSource sourceOf(const DemTerrain& dem) {
  return {dem.path,          dem.crsWkt, dem.width,
          dem.height,        dem.geotransform, dem.band,
          dem.verticalUnit.name, dem.verticalUnit.metresPerUnit};
}

}  // namespace

std::uint64_t estimatedPeakBytes(const TreeFile& tree, const SourceOptions& o) {
  const bool cartesian = std::holds_alternative<TerrainIndex>(tree.index);
  const memory::PerItem then = !cartesian ? memory::kCurvedIndex : o.heightsOnly ? memory::kGridIndex : memory::kCartesianIndex;
  const std::uint64_t w = static_cast<std::uint64_t>(std::max(tree.source.width, 0));
  const std::uint64_t h = static_cast<std::uint64_t>(std::max(tree.source.height, 0));
  if (w > 0 && h > 0 && !isTreeFile(o.source)) {
    const std::uint64_t v = w * h, t = w > 1 && h > 1 ? 2 * (w - 1) * (h - 1) : 0;
    return memory::kProcessBase + memory::kDemMesh.bytes(v, t) + then.bytes(v, t);
  }
  return std::visit(
      [&](const auto& index) { return memory::kProcessBase + then.bytes(index.stats().vertices, index.stats().triangles); },
      tree.index);
}

const char* mappingNameOf(const AnyIndex& index) {
  return std::visit([](const auto& i) { return i.mapping().name(); }, index);
}

void requireSource(const std::string& path) {
  // GDAL's virtual paths (/vsizip/, /vsicurl/...) are not on the file system.
  if (path.rfind("/vsi", 0) != 0 && !std::filesystem::exists(path)) {
    throw Error(path + ": cannot open: no such file");
  }
}

TreeFile openIndex(const SourceOptions& o) {
  requireSource(o.source);
  DemOptions demOptions;
  demOptions.band = o.band;
  demOptions.lonLatAsCartesian = true;
  const bool cartesian = o.mapping.empty() || o.mapping == "cartesian";
  demOptions.then = !cartesian ? memory::kCurvedIndex : o.heightsOnly ? memory::kGridIndex : memory::kCartesianIndex;
  if (isTreeFile(o.source)) {
    TreeFile tf = loadTree(o.source);
    if (o.band != 0 && o.band != tf.source.band) {
      throw Error(o.source + ": the tree file was built from band " + std::to_string(tf.source.band) +
                  " of " + tf.source.path + ", not band " + std::to_string(o.band));
    }
    if (!o.heightRef.empty()) {
      throw Error(o.source + ": --height-ref is given when a tree file is built (qota build); this one's heights are over the " +
                  (tf.source.geoidGrid.empty() ? std::string("ellipsoid") : tf.source.heightRef));
    }
    if (!o.mapping.empty() && o.mapping != mappingNameOf(tf.index)) {
      throw Error(o.source + ": the tree file was built in the " +
                  std::string(mappingNameOf(tf.index)) + " mapping, not " + o.mapping +
                  " (leave --mapping out or rebuild it)");
    }
    return tf;
  }
  if (!o.heightRef.empty() && (o.mapping != "geodetic" || !isRaster(o.source))) {
    throw Error("--height-ref applies to a raster's heights placed on an ellipsoid (--mapping geodetic); the " +
                (o.mapping.empty() ? std::string("cartesian") : o.mapping) + " mapping of " + o.source +
                " keeps its heights as they are");
  }
  if (!isRaster(o.source)) {
    // A mesh file, in world coordinates: the mapping's default frame (a sphere or cylinder
    // about the origin's z axis, the WGS84 ellipsoid with ECEF coordinates).
    if (o.band != 0) throw Error(o.source + ": -b applies to rasters; this is a mesh file");
    const MeshFile file = loadMeshFile(o.source);
    TreeSource source;
    source.path = o.source;
    source.crsWkt = file.crsWkt;
    if (o.mapping.empty() || o.mapping == "cartesian") {
      return {TerrainIndex(file.mesh, CartesianMapping(Eigen::Vector3d(0, 0, -1), file.origin),
                           o.terrain),
              source};
    }
    if (o.mapping == "spherical") return {SphericalIndex(file.mesh, SphericalMapping(), o.terrain), source};
    if (o.mapping == "geodetic") return {GeodeticIndex(file.mesh, GeodeticMapping(), o.terrain), source};
    if (o.mapping == "cylindrical") {
      return {CylindricalIndex(file.mesh, CylindricalMapping(), o.terrain), source};
    }
  }
  if (o.mapping.empty() || o.mapping == "cartesian") {
    const DemTerrain dem = loadDem(o.source, demOptions);
    return {TerrainIndex(dem.mesh, dem.mapping, o.terrain), sourceOf(dem)};
  }
  if (o.mapping == "spherical") {
    PlanetOptions planetOptions;
    planetOptions.radius = o.radius;
    planetOptions.dem = demOptions;
    const PlanetTerrain planet = loadPlanet(o.source, planetOptions);
    return {SphericalIndex(planet.dem.mesh, planet.mapping, o.terrain), sourceOf(planet.dem)};
  }
  if (o.mapping == "geodetic") {
    demOptions.heightRef = o.heightRef;
    const EllipsoidTerrain t = loadOnEllipsoid(o.source, demOptions);
    TreeSource source = sourceOf(t.dem);
    source.heightRef = t.heightRef.describe();
    source.geoidGrid = t.heightRef.grid;
    return {GeodeticIndex(t.dem.mesh, t.mapping, o.terrain), source};
  }

  if (o.mapping == "cylindrical") {
    // The raster is the station's relief: columns around the axis, rows along it.
    const DemTerrain dem = loadDem(o.source, demOptions);
    Heightfield relief;
    relief.nx = dem.width, relief.ny = dem.height;
    relief.z.resize(dem.mesh.vertices.size());
    // Relief in metres: the station's geometry is metric.
    const double metres = dem.verticalUnit.metresPerUnit;
    for (std::size_t i = 0; i < relief.z.size(); ++i) relief.z[i] = dem.mesh.vertices[i].z() * metres;
    StationOptions station;
    if (o.radius > 0) station.radius = o.radius;
    if (o.length > 0) station.length = o.length;
    TreeSource source = sourceOf(dem);
    source.width = source.height = 0;  // not a map: no raster footprint to check points against
    return {CylindricalIndex(stationMesh(relief, station), CylindricalMapping(), o.terrain), source};
  }
  throw Error("--mapping '" + o.mapping + "' is not one of cartesian, spherical, cylindrical, geodetic");
}

}  // namespace qota::tools
