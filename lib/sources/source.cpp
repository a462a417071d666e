#include "qota/source.hpp"

#include <gdal_priv.h>

#include <algorithm>
#include <filesystem>
#include <memory>
#include <type_traits>

#include "gdal_errors.hpp"
#include <GeographicLib/Geocentric.hpp>

#include "qota/dem.hpp"
#include "qota/enu.hpp"
#include "qota/error.hpp"
#include "qota/globe.hpp"
#include "qota/mapping_registry.hpp"
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
  return {dem.path,
          dem.crsWkt,
          dem.width,
          dem.height,
          dem.geotransform,
          dem.band,
          dem.verticalUnit.name,
          dem.verticalUnit.metresPerUnit};
}

}  // namespace

std::uint64_t estimatedPeakBytes(const TreeFile& tree, const SourceOptions& o) {
  const bool cartesian = std::holds_alternative<CartesianIndex>(tree.index);
  const memory::PerItem then = !cartesian      ? memory::kCurvedIndex
                               : o.heightsOnly ? memory::kGridIndex
                                               : memory::kCartesianIndex;
  const std::uint64_t w = static_cast<std::uint64_t>(std::max(tree.source.width, 0));
  const std::uint64_t h = static_cast<std::uint64_t>(std::max(tree.source.height, 0));
  if (w > 0 && h > 0 && !isTreeFile(o.source)) {
    const std::uint64_t v = w * h, t = w > 1 && h > 1 ? 2 * (w - 1) * (h - 1) : 0;
    return memory::kProcessBase + memory::kDemMesh.bytes(v, t) + then.bytes(v, t);
  }
  return std::visit(
      [&](const auto& index) {
        return memory::kProcessBase + then.bytes(index.stats().vertices, index.stats().triangles);
      },
      tree.index);
}

const MappingEntry& mappingEntry(std::string_view name) {
  if (name.empty()) return kMappingEntries[0];
  for (const MappingEntry& e : kMappingEntries) {
    if (name == e.name) return e;
  }
  throw Error("mapping '" + std::string(name) + "' is not one of " + mappingNames());
}

std::vector<std::string> mappingNameList() {
  std::vector<std::string> names;
  names.reserve(kMappingEntries.size());
  for (const MappingEntry& e : kMappingEntries) names.emplace_back(e.name);
  return names;
}

std::string mappingHelp() {
  std::string help;
  for (const MappingEntry& e : kMappingEntries) {
    if (!help.empty()) help += "; ";
    help += std::string(e.name) + " (" + e.raster + "; lines '" + e.line + "', prints " + e.answer + ")";
  }
  return help;
}

std::string mappingsWith(bool MappingEntry::*flag) {
  std::vector<const char*> names;
  for (const MappingEntry& e : kMappingEntries) {
    if (e.*flag) names.push_back(e.name);
  }
  std::string text;
  for (std::size_t i = 0; i < names.size(); ++i) {
    text += (i == 0 ? "" : i + 1 == names.size() ? " or " : ", ");
    text += names[i];
  }
  return text;
}

void requireMappingOptions(const SourceOptions& o) {
  const MappingEntry& entry = mappingEntry(o.mapping);
  requireMappingTakes(entry, o.radius != 0, &MappingEntry::radius, "--radius");
  requireMappingTakes(entry, o.length != 0, &MappingEntry::length, "--length");
  requireMappingTakes(entry, o.origin.has_value(), &MappingEntry::origin, "--origin");
  requireMappingTakes(entry, !o.heightRef.empty(), &MappingEntry::ellipsoid, "--height-ref");
}

void requireMappingTakes(const MappingEntry& entry, bool given, bool MappingEntry::*flag, const std::string& what) {
  if (given && !(entry.*flag)) {
    throw Error(what + " applies to the " + mappingsWith(flag) + " mapping, not " + entry.name);
  }
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

namespace {

// A mesh in world coordinates in each mapping's default frame (meshIndex): one overload per
// mapping, chosen by its type.
struct MeshPlacement {
  const Mesh& mesh;
  const Eigen::Vector3d& cartesianOrigin;
  const std::optional<std::array<double, 3>>& origin;
  const IndexOptions& terrain;

  AnyIndex in(std::type_identity<CartesianMapping>) const {
    return CartesianIndex(mesh, CartesianMapping(Eigen::Vector3d(0, 0, -1), cartesianOrigin), terrain);
  }
  AnyIndex in(std::type_identity<SphericalMapping>) const { return SphericalIndex(mesh, SphericalMapping(), terrain); }
  AnyIndex in(std::type_identity<GeodeticMapping>) const { return GeodeticIndex(mesh, GeodeticMapping(), terrain); }
  AnyIndex in(std::type_identity<CylindricalMapping>) const {
    return CylindricalIndex(mesh, CylindricalMapping(), terrain);
  }
  AnyIndex in(std::type_identity<EnuMapping>) const {
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
        throw Error("the enu mapping takes ECEF vertices on the Earth; these are centred " + std::to_string(c.norm()) +
                    " m from its centre (give the origin, or another mapping)");
      }
      GeographicLib::Geocentric::WGS84().Reverse(c.x(), c.y(), c.z(), at[0], at[1], at[2]);
    }
    return EnuIndex(mesh, EnuMapping(at[0], at[1], at[2]), terrain);
  }
};

}  // namespace

AnyIndex meshIndex(const Mesh& mesh, const std::string& mapping, const Eigen::Vector3d& cartesianOrigin,
                   const std::optional<std::array<double, 3>>& origin, const IndexOptions& terrain) {
  const MappingEntry& entry = mappingEntry(mapping);
  requireMappingTakes(entry, origin.has_value(), &MappingEntry::origin, "--origin");
  const MeshPlacement place{mesh, cartesianOrigin, origin, terrain};
  return withMapping(mapping, [&]<class M>() { return place.in(std::type_identity<M>{}); });
}

namespace {

// A raster placed in each mapping (openIndex): one overload per mapping, chosen by its type.
struct RasterPlacement {
  const SourceOptions& o;
  DemOptions demOptions;

  TreeFile in(std::type_identity<CartesianMapping>) const {
    const DemTerrain dem = loadDem(o.source, demOptions);
    return {CartesianIndex(dem.mesh, dem.mapping, o.index), sourceOf(dem)};
  }
  TreeFile in(std::type_identity<SphericalMapping>) const {
    PlanetOptions planetOptions;
    planetOptions.radius = o.radius;
    planetOptions.dem = demOptions;
    const PlanetTerrain planet = loadPlanet(o.source, planetOptions);
    return {SphericalIndex(planet.dem.mesh, planet.mapping, o.index), sourceOf(planet.dem)};
  }
  TreeFile in(std::type_identity<GeodeticMapping>) const {
    const EllipsoidTerrain t = onEllipsoid();
    TreeSource source = sourceOf(t.dem);
    source.heightRef = t.heightRef.describe();
    source.geoidGrid = t.heightRef.grid;
    return {GeodeticIndex(t.dem.mesh, t.mapping, o.index), source};
  }
  TreeFile in(std::type_identity<EnuMapping>) const {
    // The DEM on its ellipsoid as the geodetic mapping places it (its heights over their
    // reference), seen in the east-north-up frame at the origin (default: the raster's centre, at
    // height 0 on the ellipsoid). Answers are metres up in that frame: no raster footprint.
    const EllipsoidTerrain t = onEllipsoid();
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
    return {EnuIndex(t.dem.mesh, EnuMapping(at[0], at[1], at[2], t.mapping.a(), t.mapping.f()), o.index), source};
  }
  TreeFile in(std::type_identity<CylindricalMapping>) const {
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
    return {CylindricalIndex(stationMesh(relief, station), CylindricalMapping(), o.index), source};
  }

 private:
  EllipsoidTerrain onEllipsoid() const {
    DemOptions options = demOptions;
    options.heightRef = o.heightRef;
    return loadOnEllipsoid(o.source, options);
  }
};

}  // namespace

TreeFile openIndex(const SourceOptions& o) {
  requireSource(o.source);
  const MappingEntry& entry = mappingEntry(o.mapping);
  DemOptions demOptions;
  demOptions.band = o.band;
  demOptions.lonLatAsCartesian = true;
  demOptions.fillVoids = o.fillVoids;
  const bool cartesian = entry.map;
  demOptions.then = !cartesian ? memory::kCurvedIndex : o.heightsOnly ? memory::kGridIndex : memory::kCartesianIndex;
  if (isTreeFile(o.source)) {
    TreeFile tf = loadTree(o.source);
    if (o.band != 0 && o.band != tf.source.band) {
      throw Error(o.source + ": the tree file was built from band " + std::to_string(tf.source.band) + " of " +
                  tf.source.path + ", not band " + std::to_string(o.band));
    }
    if (!o.heightRef.empty()) {
      throw Error(o.source +
                  ": --height-ref is given when a tree file is built (qota build); this one's heights are over the " +
                  (tf.source.geoidGrid.empty() ? std::string("ellipsoid") : tf.source.heightRef));
    }
    if (!o.mapping.empty() && o.mapping != mappingNameOf(tf.index)) {
      throw Error(o.source + ": the tree file was built in the " + std::string(mappingNameOf(tf.index)) +
                  " mapping, not " + o.mapping + " (leave --mapping out or rebuild it)");
    }
    return tf;
  }
  requireMappingOptions(o);
  if (!isRaster(o.source)) {
    // A mesh file, in world coordinates: the mapping's default frame (a sphere or cylinder
    // about the origin's z axis, the WGS84 ellipsoid with ECEF coordinates).
    if (o.band != 0) throw Error(o.source + ": -b applies to rasters; this is a mesh file");
    if (!o.heightRef.empty())
      throw Error("--height-ref applies to a raster's heights; " + o.source + " is a mesh file");
    const MeshFile file = loadMeshFile(o.source);
    TreeSource source;
    source.path = o.source;
    source.crsWkt = file.crsWkt;
    return {meshIndex(file.mesh, o.mapping, file.origin, o.origin, o.index), source};
  }
  const RasterPlacement place{o, demOptions};
  return withMapping(o.mapping, [&]<class M>() { return place.in(std::type_identity<M>{}); });
}

}  // namespace qota
