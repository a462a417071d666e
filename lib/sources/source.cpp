#include "qota/source.hpp"

#include <gdal_priv.h>

#include <algorithm>
#include <filesystem>
#include <memory>

#include "gdal_errors.hpp"
#include <GeographicLib/Geocentric.hpp>

#include "qota/dem.hpp"
#include "qota/enu.hpp"
#include "qota/error.hpp"
#include "qota/globe.hpp"
#include "qota/mesh_io.hpp"

namespace qota {

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

AnyIndex meshIndex(const Mesh& mesh, const std::string& mapping, const Eigen::Vector3d& cartesianOrigin,
                   const std::optional<std::array<double, 3>>& origin, const IndexOptions& terrain) {
  if (origin && mapping != "enu") throw Error("--origin applies to the enu mapping (the frame's origin)");
  if (mapping.empty() || mapping == "cartesian") {
    return TerrainIndex(mesh, CartesianMapping(Eigen::Vector3d(0, 0, -1), cartesianOrigin), terrain);
  }
  if (mapping == "spherical") return SphericalIndex(mesh, SphericalMapping(), terrain);
  if (mapping == "geodetic") return GeodeticIndex(mesh, GeodeticMapping(), terrain);
  if (mapping == "cylindrical") return CylindricalIndex(mesh, CylindricalMapping(), terrain);
  if (mapping == "enu") {
    // ECEF vertices (a city model in EPSG:4978) seen from the origin, by default the point of the
    // ellipsoid under the centre of their box, at that centre's height.
    std::array<double, 3> at{0, 0, 0};
    if (origin) {
      at = *origin;
    } else {
      Eigen::Vector3d lo = Eigen::Vector3d::Constant(INFINITY), hi = -lo;
      for (const Eigen::Vector3d& v : mesh.vertices) lo = lo.cwiseMin(v), hi = hi.cwiseMax(v);
      const Eigen::Vector3d c = 0.5 * (lo + hi);
      if (c.norm() < 1e5) {
        throw Error("the enu mapping takes ECEF vertices on the Earth; these are centred " +
                    std::to_string(c.norm()) + " m from its centre (give the origin, or another mapping)");
      }
      GeographicLib::Geocentric::WGS84().Reverse(c.x(), c.y(), c.z(), at[0], at[1], at[2]);
    }
    return EnuIndex(mesh, EnuMapping(at[0], at[1], at[2]), terrain);
  }
  throw Error("mapping '" + mapping + "' is not one of cartesian, spherical, geodetic, cylindrical, enu");
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
  if (o.origin && o.mapping != "enu") throw Error("--origin applies to the enu mapping (the frame's origin)");
  if (!o.heightRef.empty() && ((o.mapping != "geodetic" && o.mapping != "enu") || !isRaster(o.source))) {
    throw Error("--height-ref applies to a raster's heights placed on an ellipsoid (--mapping geodetic or enu); the " +
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
    return {meshIndex(file.mesh, o.mapping, file.origin, o.origin, o.terrain), source};
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

  if (o.mapping == "enu") {
    // The DEM on its ellipsoid as the geodetic mapping places it (its heights over their
    // reference), seen in the east-north-up frame at the origin (default: the raster's centre, at
    // height 0 on the ellipsoid). Answers are metres up in that frame: no raster footprint.
    demOptions.heightRef = o.heightRef;
    const EllipsoidTerrain t = loadOnEllipsoid(o.source, demOptions);
    std::array<double, 3> at{0, 0, 0};
    if (o.origin) {
      at = *o.origin;
    } else {
      const auto centre = t.dem.pixelCentre((t.dem.width - 1) / 2.0, (t.dem.height - 1) / 2.0);
      at = {centre[1], centre[0], 0.0};
    }
    TreeSource source = sourceOf(t.dem);
    source.width = source.height = 0;
    source.heightRef = t.heightRef.describe();
    source.metresPerUnit = 1;  // (answers in the frame's metres)
    return {EnuIndex(t.dem.mesh, EnuMapping(at[0], at[1], at[2], t.mapping.a(), t.mapping.f()), o.terrain), source};
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
  throw Error("--mapping '" + o.mapping + "' is not one of cartesian, spherical, geodetic, cylindrical, enu");
}

}  // namespace qota
