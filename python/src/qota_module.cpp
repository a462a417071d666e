// qota._qota: the library's terrain indexes for numpy arrays. The Python side (python/qota/
// __init__.py) checks, broadcasts and reshapes; here every call takes flat float64 arrays,
// answers with the library's parallel batches with the GIL released, and maps "no terrain" to
// NaN. One Terrain class holds an index of any mapping the package reads.
#include <gdal_priv.h>
#include <ogr_spatialref.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <array>
#include <atomic>
#include <cmath>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>
#include <variant>
#include <vector>

#include "qota/crs_transform.hpp"
#include "qota/any_index.hpp"
#include "qota/batch.hpp"
#include "qota/curved.hpp"
#include "qota/dem.hpp"
#include "qota/error.hpp"
#include "qota/mapping_registry.hpp"
#include "qota/instant.hpp"
#include "qota/kernel_sampler.hpp"
#include "qota/raster_sampler.hpp"
#include "qota/geoid.hpp"
#include "qota/terrain_face.hpp"
#include "qota/shadow_tiles.hpp"
#include "qota/sun.hpp"
#include "qota/sunlight.hpp"
#include "qota/terrain.hpp"
#include "qota/viewshed.hpp"
#include "qota/treefile.hpp"
#include "qota/version.hpp"
#include "qota_tools.hpp"

namespace py = pybind11;

namespace {

using Array = py::array_t<double, py::array::c_style | py::array::forcecast>;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// A terrain in any mapping (qota::Terrain, qota/terrain_face.hpp: points in the source's own
// coordinates, heights in its unit and vertical reference), batched over numpy arrays with the
// GIL released. The Python package reads the cartesian (vertical gravity), spherical, geodetic
// and cylindrical mappings; another is refused with the face's message.
class Terrain {
 public:
  explicit Terrain(qota::TreeFile tree) : t_(std::move(tree)) {}

  py::array_t<double> heights(const Array& x, const Array& y) const {
    return batch(x, y, nullptr, [this](auto xs, auto ys, auto, auto out) { t_.heights(xs, ys, out); });
  }
  py::array_t<double> below(const Array& x, const Array& y, const Array& z) const {
    return batch(x, y, &z, [this](auto xs, auto ys, auto zs, auto out) { t_.below(xs, ys, zs, out); });
  }
  py::array_t<double> above(const Array& x, const Array& y, const Array& z) const {
    return batch(x, y, &z, [this](auto xs, auto ys, auto zs, auto out) { t_.above(xs, ys, zs, out); });
  }

  // The top hit (mode "top", z unused), or the nearest hit below or above z ("below", "above") at
  // every point, with what it hit: heights (NaN: none), polygon ids (-1: none) and unit normals in
  // the world frame (NaN: none), on every core with the GIL released.
  py::tuple hits(const Array& x, const Array& y, const std::optional<Array>& z, const std::string& mode) const {
    const int kind = mode == "top" ? 0 : mode == "below" ? 1 : mode == "above" ? 2 : -1;
    if (kind < 0) throw qota::Error("hits: mode must be top, below or above, not '" + mode + "'");
    if (kind > 0 && !z) throw qota::Error("hits: " + mode + " needs z");
    requireFlat(x, y, kind > 0 ? &*z : nullptr);
    const auto n = static_cast<std::size_t>(x.shape(0));
    py::array_t<double> heights(static_cast<py::ssize_t>(n));
    py::array_t<std::int64_t> polygons(static_cast<py::ssize_t>(n));
    py::array_t<double> normals({static_cast<py::ssize_t>(n), py::ssize_t{3}});
    const double *px = x.data(), *py_ = y.data(), *pz = kind > 0 ? z->data() : nullptr;
    double* h = heights.mutable_data();
    std::int64_t* p = polygons.mutable_data();
    double* nrm = normals.mutable_data();
    {
      py::gil_scoped_release release;
      std::visit(
          [&](const auto& index) {
            qota::batch::inSlices(n, 0, 4096, [&](std::size_t lo, std::size_t hi) {
              for (std::size_t i = lo; i < hi; ++i) {
                const qota::Point2 q = t_.mapped(px[i], py_[i]);
                const auto hit = kind == 0   ? index.top(q.u, q.v)
                                 : kind == 1 ? index.below(q.u, q.v, t_.toIndex(pz[i], q, 1))
                                             : index.above(q.u, q.v, t_.toIndex(pz[i], q, -1));
                h[i] = hit ? t_.fromIndex(hit->height, q) : kNaN;
                p[i] = hit ? static_cast<std::int64_t>(hit->polygon) : -1;
                for (int k = 0; k < 3; ++k) nrm[3 * i + k] = hit ? hit->normal[k] : kNaN;
              }
            });
          },
          t_.index());
    }
    return py::make_tuple(heights, polygons, normals);
  }

  // Every surface on the line of (x, y), top first: (height, polygon id, normal).
  std::vector<py::tuple> all(double x, double y) const {
    std::vector<py::tuple> out;
    for (const qota::Hit& h : t_.all(x, y)) {
      out.push_back(py::make_tuple(h.height, h.polygon, py::make_tuple(h.normal.x(), h.normal.y(), h.normal.z())));
    }
    return out;
  }

  void save(const std::string& path) const {
    py::gil_scoped_release release;
    qota::saveTree(path, t_.index(), t_.source());
  }

  py::dict stats() const {
    const qota::IndexStats s = std::visit([](const auto& index) { return index.stats(); }, t_.index());
    py::dict d;
    d["polygons"] = s.polygons;
    d["triangles"] = s.triangles;
    d["vertices"] = s.vertices;
    d["nodes"] = s.tree.nodes;
    d["memory_bytes"] = s.memoryBytes;
    return d;
  }

  const std::string& source() const { return t_.source().path; }
  std::string mapping() const { return t_.mapping(); }
  const std::string& crs() const { return t_.source().crsWkt; }
  std::string heightRef() const { return t_.heightRef(); }
  // A lon/lat raster in the cartesian mapping: x, y in degrees, z in metres (heights are right,
  // normals are not).
  bool lonLatMap() const { return !t_.normalsMetric(); }

 private:
  static void requireFlat(const Array& x, const Array& y, const Array* z) {
    if (x.ndim() != 1 || y.ndim() != 1 || x.shape(0) != y.shape(0) ||
        (z && (z->ndim() != 1 || z->shape(0) != x.shape(0)))) {
      throw qota::Error("x, y (and z) must be flat arrays of one length");
    }
  }

  // run(x, y, z, out) over the arrays' spans with the GIL released; NaN for no terrain.
  template <class Run>
  py::array_t<double> batch(const Array& x, const Array& y, const Array* z, Run&& run) const {
    requireFlat(x, y, z);
    const std::size_t n = static_cast<std::size_t>(x.shape(0));
    py::array_t<double> result(static_cast<py::ssize_t>(n));
    const std::span<const double> xs(x.data(), n), ys(y.data(), n), zs(z ? z->data() : nullptr, z ? n : 0);
    const std::span<double> out(result.mutable_data(), n);
    {
      py::gil_scoped_release release;
      run(xs, ys, zs, out);
    }
    return result;
  }

  qota::Terrain t_;
};

// The raster options of `qota sample --mapping --radius --length`, checked as the tool checks
// them (positive numbers), and refused where they do not apply rather than ignored.
qota::tools::SourceOptions rasterOptions(const std::string& path, int band, const std::string& mapping,
                                         std::optional<double> radius, std::optional<double> length,
                                         std::optional<std::array<double, 3>> origin = std::nullopt) {
  // (the registry says which mapping takes which option; the messages name Python's arguments)
  const qota::MappingEntry& entry = qota::mappingEntry(mapping);
  qota::requireMappingTakes(entry, radius.has_value(), &qota::MappingEntry::radius, "radius");
  qota::requireMappingTakes(entry, length.has_value(), &qota::MappingEntry::length, "length");
  qota::requireMappingTakes(entry, origin.has_value(), &qota::MappingEntry::origin, "origin");
  if (radius && !(*radius > 0 && std::isfinite(*radius))) throw qota::Error("radius must be a positive number");
  if (length && !(*length > 0 && std::isfinite(*length))) throw qota::Error("length must be a positive number");
  qota::tools::SourceOptions o;
  o.source = path;
  o.band = band;
  o.mapping = mapping;
  o.radius = radius.value_or(0.0);  // 0: the tool's defaults (the CRS's radius; 250 and 1000)
  o.length = length.value_or(0.0);
  o.origin = origin;
  return o;
}

// A raster in a mapping, as `qota sample --mapping` builds it (the tools' openIndex). The file
// is first opened as a raster, so that a tree or mesh file is refused here with GDAL's reason
// rather than read as something else.
qota::TreeFile rasterTree(const qota::tools::SourceOptions& o) {
  if (qota::isTreeFile(o.source)) throw qota::Error(o.source + ": a tree file, not a raster (Terrain.load reads it)");
  qota::DemOptions check;
  check.band = o.band;
  check.lonLatAsCartesian = true;
  qota::describeDem(o.source, check);
  return qota::tools::openIndex(o);
}

Terrain fromRaster(const std::string& path, int band, const std::string& mapping, std::optional<double> radius,
                   std::optional<double> length, const std::string& heightRef,
                   std::optional<std::array<double, 3>> origin) {
  qota::tools::SourceOptions o = rasterOptions(path, band, mapping, radius, length, origin);
  o.heightRef = heightRef;
  qota::requireMappingTakes(qota::mappingEntry(o.mapping), !heightRef.empty(), &qota::MappingEntry::ellipsoid,
                            "height_ref");
  py::gil_scoped_release release;
  return Terrain(rasterTree(o));
}

// Creates a one-band Float64 GeoTIFF of rows x cols at `path` (a file, or GDAL's memory file
// system) with the geotransform, nodata, CRS (any text GDAL's SetFromUserInput reads: WKT,
// EPSG:4326, PROJ) and vertical unit (the band's unit type, which loadDem and qota shadow read)
// given, its pixels not yet written. sparse: blocks never written take no room (a description of
// a raster, its pixels elsewhere). Nothing here touches Python, so the caller may release the GIL
// around it.
std::unique_ptr<GDALDataset> createRaster(const std::string& path, int rows, int cols,
                                          const std::vector<double>& transform, std::optional<double> nodata,
                                          const std::string& crs, const std::string& unit, bool sparse = false) {
  qota::ensureGdalRegistered();
  OGRSpatialReference srs;
  if (!crs.empty()) {
    CPLPushErrorHandler(CPLQuietErrorHandler);  // the message is ours; GDAL's would go to stderr
    const OGRErr read = srs.SetFromUserInput(crs.c_str());
    CPLPopErrorHandler();
    if (read != OGRERR_NONE) {
      throw qota::Error("crs '" + crs.substr(0, 80) + "' is not a coordinate reference system GDAL knows");
    }
  }
  GDALDriver* gtiff = GetGDALDriverManager()->GetDriverByName("GTiff");
  const char* options[] = {sparse ? "SPARSE_OK=TRUE" : nullptr, nullptr};
  std::unique_ptr<GDALDataset> ds(gtiff->Create(path.c_str(), cols, rows, 1, GDT_Float64, const_cast<char**>(options)));
  if (!ds) throw qota::Error(path + ": cannot create the raster for the array");
  double gt[6];
  std::copy(transform.begin(), transform.end(), gt);
  ds->SetGeoTransform(gt);
  if (!crs.empty()) ds->SetSpatialRef(&srs);
  GDALRasterBand* b = ds->GetRasterBand(1);
  if (nodata) b->SetNoDataValue(*nodata);
  if (!unit.empty()) b->SetUnitType(unit.c_str());
  return ds;
}

// The same raster with the 2-D float64 array's values as its pixels.
void writeRasterFile(const std::string& path, const double* data, int rows, int cols,
                     const std::vector<double>& transform, std::optional<double> nodata, const std::string& crs,
                     const std::string& unit) {
  std::unique_ptr<GDALDataset> ds = createRaster(path, rows, cols, transform, nodata, crs, unit);
  if (ds->GetRasterBand(1)->RasterIO(GF_Write, 0, 0, cols, rows, const_cast<double*>(data), cols, rows, GDT_Float64, 0,
                                     0) != CE_None) {
    throw qota::Error(path + ": cannot write the array into the raster");
  }
  ds.reset();  // closed: flushed for whoever reads it next
}

void checkTransform(const std::vector<double>& transform) {
  if (transform.size() != 6) throw qota::Error("transform must have 6 numbers (GDAL's geotransform)");
  for (double t : transform) {
    if (!std::isfinite(t)) throw qota::Error("transform has a value that is not finite");
  }
  if (transform[1] * transform[5] - transform[2] * transform[4] == 0) {
    throw qota::Error("transform is singular (a pixel of zero area)");
  }
}

// The checks on an array and its geotransform that GDAL would not make (or would make with a
// less clear message).
void checkGrid(const py::array_t<double, py::array::c_style | py::array::forcecast>& heights,
               const std::vector<double>& transform) {
  if (heights.ndim() != 2) throw qota::Error("heights must be a 2-D array (rows, columns)");
  if (heights.shape(0) < 2 || heights.shape(1) < 2) {
    throw qota::Error("heights of " + std::to_string(heights.shape(0)) + " x " + std::to_string(heights.shape(1)) +
                      " values: at least 2 x 2 are needed (the values are the pixel centres, and one row or "
                      "column of them spans no surface)");
  }
  if (heights.shape(0) > std::numeric_limits<int>::max() || heights.shape(1) > std::numeric_limits<int>::max()) {
    throw qota::Error("heights has more rows or columns than GDAL takes");
  }
  checkTransform(transform);
}

void writeRaster(const std::string& path, py::array_t<double, py::array::c_style | py::array::forcecast> heights,
                 const std::vector<double>& transform, std::optional<double> nodata, const std::string& crs,
                 const std::string& unit) {
  checkGrid(heights, transform);
  const int rows = static_cast<int>(heights.shape(0)), cols = static_cast<int>(heights.shape(1));
  const double* data = heights.data();
  py::gil_scoped_release release;
  writeRasterFile(path, data, rows, cols, transform, nodata, crs, unit);
}

// A numpy array with a GDAL geotransform: written as a GeoTIFF in GDAL's memory file system and
// read back as from_raster reads a file, so the array's terrain is exactly the raster's (pixel
// centres, nodata holes), in any mapping.
Terrain fromArray(py::array_t<double, py::array::c_style | py::array::forcecast> heights,
                  const std::vector<double>& transform, std::optional<double> nodata, const std::string& crs,
                  const std::string& unit, const std::string& mapping, std::optional<double> radius,
                  std::optional<double> length, const std::string& heightRef,
                  std::optional<std::array<double, 3>> origin) {
  checkGrid(heights, transform);
  static std::atomic<unsigned> counter{0};
  const std::string path = "/vsimem/qota_python_" + std::to_string(counter++) + ".tif";
  qota::tools::SourceOptions o = rasterOptions(path, 1, mapping, radius, length, origin);
  o.heightRef = heightRef;
  qota::requireMappingTakes(qota::mappingEntry(o.mapping), !heightRef.empty(), &qota::MappingEntry::ellipsoid,
                            "height_ref");
  const int rows = static_cast<int>(heights.shape(0)), cols = static_cast<int>(heights.shape(1));
  const double* data = heights.data();
  py::gil_scoped_release release;
  try {
    writeRasterFile(path, data, rows, cols, transform, nodata, crs, unit);
    qota::TreeFile tree = rasterTree(o);
    VSIUnlink(path.c_str());
    tree.source.path = "<array>";
    return Terrain(std::move(tree));
  } catch (...) {
    VSIUnlink(path.c_str());
    throw;
  }
}

// A mesh in world coordinates, in a mapping's default frame, as `qota build --mapping` reads a
// mesh file: cartesian with gravity -Z (the origin at the centre of the footprint, z 0, so
// heights stay in the mesh's own z), a sphere about the origin, the WGS84 ellipsoid in ECEF
// metres, a cylinder about the z axis.
Terrain fromMesh(py::array_t<double, py::array::c_style | py::array::forcecast> vertices,
                 py::array_t<std::int64_t, py::array::c_style | py::array::forcecast> triangles,
                 const std::string& mapping, std::optional<std::array<double, 3>> origin) {
  qota::requireMappingTakes(qota::mappingEntry(mapping), origin.has_value(), &qota::MappingEntry::origin, "origin");
  if (vertices.ndim() != 2 || vertices.shape(1) != 3) throw qota::Error("vertices must be an (N, 3) array");
  if (triangles.ndim() != 2 || triangles.shape(1) != 3) throw qota::Error("triangles must be an (M, 3) array");
  const auto n = static_cast<std::size_t>(vertices.shape(0)), m = static_cast<std::size_t>(triangles.shape(0));
  if (n > 0xffffffffu) throw qota::Error("more than 2^32 vertices");
  const double* v = vertices.data();
  const std::int64_t* t = triangles.data();
  py::gil_scoped_release release;
  qota::Mesh mesh;
  mesh.vertices.reserve(n);
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d p(v[3 * i], v[3 * i + 1], v[3 * i + 2]);
    if (!p.allFinite()) throw qota::Error("vertex " + std::to_string(i) + " is not finite");
    mesh.vertices.push_back(p);
    lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  }
  mesh.indices.reserve(3 * m);
  for (std::size_t k = 0; k < 3 * m; ++k) {
    if (t[k] < 0 || static_cast<std::uint64_t>(t[k]) >= n) {
      throw qota::Error("triangle " + std::to_string(k / 3) + " names vertex " + std::to_string(t[k]) +
                        ", not one of the " + std::to_string(n) + " vertices");
    }
    mesh.indices.push_back(static_cast<std::uint32_t>(t[k]));
  }
  if (n == 0 || m == 0) throw qota::Error("the mesh has no triangles");
  // (origin: the enu frame's, checked by meshIndex as the tools check it)
  qota::AnyIndex index =
      qota::meshIndex(mesh, mapping, {0.5 * (lo.x() + hi.x()), 0.5 * (lo.y() + hi.y()), 0.0}, origin);
  qota::TreeSource source;
  source.path = "<mesh>";
  return Terrain(qota::TreeFile{std::move(index), source});
}

// A tree file, in the mapping it was built in.
Terrain load(const std::string& path) {
  py::gil_scoped_release release;
  qota::TreeFile tree = qota::loadTree(path);
  if (tree.source.path.empty()) tree.source.path = path;
  const std::string source = tree.source.path;
  try {
    return Terrain(std::move(tree));
  } catch (const qota::Error& e) {  // named by the tree file, not its source
    std::string what = e.what();
    if (what.rfind(source + ": ", 0) == 0) what = what.substr(source.size() + 2);
    throw qota::Error(path + ": " + what);
  }
}

// A tool run quietly with the GIL released, and the raster it wrote (band 1 of o.output) read
// back as an array; its error as a qota.Error when it failed.
template <class Options>
py::array toolRaster(const char* tool, int (*run)(const Options&, std::ostream&, std::ostream&), const Options& o,
                     bool floats) {
  std::ostringstream out, err;
  int code = 0;
  {
    py::gil_scoped_release release;
    code = run(o, out, err);
  }
  const std::string& output = o.output;
  if (code != 0) {
    std::string message = err.str();
    while (!message.empty() && message.back() == '\n') message.pop_back();
    throw qota::Error(message.empty() ? std::string("qota ") + tool + " failed" : message);
  }
  qota::ensureGdalRegistered();
  std::unique_ptr<GDALDataset> ds(GDALDataset::Open(output.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
  const std::string unreadable = output + ": cannot read the " + tool + " raster back";
  if (!ds) throw qota::Error(unreadable);
  const int w = ds->GetRasterXSize(), h = ds->GetRasterYSize();
  py::array pixels = floats ? py::array(py::array_t<float>({h, w})) : py::array(py::array_t<std::uint8_t>({h, w}));
  if (ds->GetRasterBand(1)->RasterIO(GF_Read, 0, 0, w, h, pixels.mutable_data(), w, h, floats ? GDT_Float32 : GDT_Byte,
                                     0, 0) != CE_None) {
    throw qota::Error(unreadable);
  }
  return pixels;
}

// qota shadow itself (the same pixels, the same checks and messages), into `output`, read back:
// uint8 lit, shadow, nodata; with hours (start, end, step), float32 hours of sunlight.
py::array shadow(const std::string& dem, const std::string& output, std::optional<double> azimuth,
                 std::optional<double> altitude, const std::string& time, const std::string& tz, int band,
                 double zFactor, std::optional<std::array<double, 3>> hours, const std::string& heightRef,
                 std::optional<std::array<double, 3>> sunVector, std::optional<std::array<double, 3>> sunVectorBody,
                 std::optional<std::array<double, 2>> subsolar, bool flat, const std::string& png) {
  qota::tools::ShadowOptions o;
  o.png = png;
  o.source = dem;
  o.output = output;
  o.quiet = true;
  o.band = band;
  o.azimuth = azimuth;
  o.altitude = altitude;
  o.time = time;
  o.tz = tz;
  o.zFactor = zFactor;
  o.hours = hours;
  o.heightRef = heightRef;
  if (sunVector) o.sunVector = Eigen::Vector3d((*sunVector)[0], (*sunVector)[1], (*sunVector)[2]);
  if (sunVectorBody) o.sunVectorBody = Eigen::Vector3d((*sunVectorBody)[0], (*sunVectorBody)[1], (*sunVectorBody)[2]);
  o.subsolar = subsolar;
  o.flat = flat;
  return toolRaster("shadow", qota::tools::shadow, o, hours.has_value());
}

// qota viewshed itself, into `output`, read back: uint8 visible, not visible, nodata, out of range.
py::array viewshed(const std::string& dem, const std::string& output, std::array<double, 2> observer,
                   const std::string& srs, double observerHeight, double targetHeight, double maxDistance, int band,
                   bool flat, const std::string& heightRef, double refraction) {
  qota::tools::ViewshedOptions o;
  o.source = dem;
  o.output = output;
  o.quiet = true;
  o.band = band;
  o.observer = observer;
  o.srs = srs;
  o.observerHeight = observerHeight;
  o.targetHeight = targetHeight;
  o.maxDistance = maxDistance;
  o.refraction = refraction;
  o.flat = flat;
  o.heightRef = heightRef;
  return toolRaster("viewshed", qota::tools::viewshed, o, false);
}

// How many of these observers (x, y in the raster's CRS, heights above the surface) see each pixel
// of the raster (qota::cumulativeViewshed), as int64 (rows, columns), -1 where the raster has no
// data: one task of qota.dask.viewsheds, whose sums keep voids negative.
py::array_t<std::int64_t> cumulative(const std::string& path, py::array_t<double, py::array::forcecast> xs,
                                     py::array_t<double, py::array::forcecast> ys,
                                     py::array_t<double, py::array::forcecast> heights, double targetHeight,
                                     double maxDistance, int band, bool flat, const std::string& heightRef) {
  if (xs.ndim() != 1 || ys.ndim() != 1 || heights.ndim() != 1 || xs.shape(0) != ys.shape(0) ||
      xs.shape(0) != heights.shape(0)) {
    throw qota::Error("observers: x, y and heights must be 1-D arrays of one length");
  }
  std::vector<qota::Observer> observers(static_cast<std::size_t>(xs.shape(0)));
  for (std::size_t k = 0; k < observers.size(); ++k) {
    const auto i = static_cast<py::ssize_t>(k);
    observers[k] = {xs.at(i), ys.at(i), heights.at(i), "observer " + std::to_string(k)};
  }
  qota::CumulativeOptions o;
  o.targetHeight = targetHeight, o.maxDistance = maxDistance, o.frame.flat = flat, o.frame.heightRef = heightRef;
  qota::CumulativeViewshed seen;
  int width = 0, height = 0;
  {
    py::gil_scoped_release release;
    qota::DemOptions demOptions;
    demOptions.band = band;
    demOptions.lonLatAsCartesian = true;
    demOptions.triangles = false;  // (the frame triangulates the grid from the heights, as qota viewshed)
    demOptions.vertices = false;
    // (As qota viewshed --observers estimates it: flat frames sweep, the ellipsoid's walk.)
    demOptions.then =
        (flat ? qota::memory::kSweptLinesOfSight : qota::memory::kWalkedLinesOfSight) + qota::memory::kCounts;
    demOptions.thenWithoutCrs = qota::memory::kSweptLinesOfSight + qota::memory::kCounts;
    const qota::DemTerrain dem = qota::loadDem(path, demOptions);
    width = dem.width, height = dem.height;
    seen = qota::cumulativeViewshed(dem, observers, o);
  }
  py::array_t<std::int64_t> out({height, width});
  std::int64_t* p = out.mutable_data();
  for (std::size_t i = 0; i < seen.count.size(); ++i) {
    p[i] = seen.valid[i] ? static_cast<std::int64_t>(seen.count[i]) : std::int64_t{-1};
  }
  return out;
}

// The Sun's apparent azimuth and altitude (degrees) seen from (lon, lat) on the Earth.
py::tuple sunPosition(const std::string& time, double lon, double lat, const std::string& tz) {
  if (!std::isfinite(lon) || !(lat >= -90 && lat <= 90)) {
    throw qota::Error("need a finite longitude and a latitude in [-90, 90]");
  }
  const qota::Instant at = qota::parseInstant(time, tz);
  const qota::SunPosition sun = qota::sunPosition(at.julianDayUT, lon, lat);
  return py::make_tuple(sun.azimuth, sun.altitude);
}

// Shadows by blocks and heights by tiles, for Dask (python/qota/dask.py): the tiles are made
// once on the client and shipped to the workers as their state (pickled); each block is computed
// from its heights with its overlap, the GIL released.

// The values of qota shadow's rasters (its defaults): lit, shadow and nodata pixels; hours' nodata.
const qota::tools::ShadowOptions kShadowDefaults{};
const auto kLitValue = static_cast<std::uint8_t>(kShadowDefaults.litValue);
const auto kShadowValue = static_cast<std::uint8_t>(kShadowDefaults.shadowValue);
const auto kNoDataValue = static_cast<std::uint8_t>(kShadowDefaults.nodataValue);
constexpr float kNoHours = -1;

// A window of pixels as Python gives it: (col, row, width, height).
using Pixels = std::array<int, 4>;
qota::PixelWindow pixelsOf(const Pixels& c) { return {c[0], c[1], c[2], c[3]}; }

// The heights of a window from a 2-D array of its shape (rows, columns).
std::vector<double> heightsOf(const Array& a, const qota::PixelWindow& w) {
  if (a.ndim() != 2 || a.shape(0) != w.height || a.shape(1) != w.width) {
    throw qota::Error("heights must be a 2-D array of the window's " + std::to_string(w.height) + " rows and " +
                      std::to_string(w.width) + " columns");
  }
  return {a.data(), a.data() + a.size()};
}

std::vector<Eigen::Vector3d> lightsOf(const std::vector<std::array<double, 3>>& lights) {
  std::vector<Eigen::Vector3d> out;
  for (const auto& l : lights) out.emplace_back(l[0], l[1], l[2]);
  return out;
}

// A raster's tiles, read once (the height range) from its file.
qota::ShadowTiles tilesFromRaster(const std::string& path, int band, double zFactor) {
  qota::DemOptions dem;
  dem.band = band;
  dem.lonLatAsCartesian = true;  // read as lon/lat: the frame puts it on its ellipsoid
  qota::FrameOptions frame;
  frame.zFactor = zFactor;
  py::gil_scoped_release release;
  return qota::ShadowTiles(path, dem, frame);
}

// Tiles of heights that only Python has (a Dask array): the description is describeDem's of a
// raster with the same grid, CRS and unit that holds no pixels (so it is what a file of these
// heights would say), and the heights come from read(col, row, width, height), a 2-D array with
// NaN for no data. Returned restored from the state, so that nothing keeps `read`.
qota::ShadowTiles tilesFromReader(int rows, int cols, const std::vector<double>& transform, const std::string& crs,
                                  const std::string& unit, const std::string& label, const py::function& read,
                                  double zFactor, int band) {
  if (rows < 1 || cols < 1) throw qota::Error("the heights need at least one row and one column");
  checkTransform(transform);
  static std::atomic<unsigned> counter{0};
  const std::string path = "/vsimem/qota_python_grid_" + std::to_string(counter++) + ".tif";
  PyObject* function = read.ptr();  // borrowed: `read` outlives this call, and no copy is made without the GIL
  const qota::ShadowTiles::HeightReader reader = [function](const qota::PixelWindow& w, std::vector<double>& out) {
    py::gil_scoped_acquire acquire;
    const auto heights =
        py::cast<Array>(py::reinterpret_borrow<py::function>(function)(w.col, w.row, w.width, w.height));
    out = heightsOf(heights, w);
  };
  qota::FrameOptions frame;
  frame.zFactor = zFactor;
  std::string state;
  {
    py::gil_scoped_release release;
    qota::DemTerrain description;
    try {
      createRaster(path, rows, cols, transform, std::nullopt, crs, unit, true).reset();
      qota::DemOptions options;
      options.lonLatAsCartesian = true;
      description = qota::describeDem(path, options);
      VSIUnlink(path.c_str());
    } catch (...) {
      VSIUnlink(path.c_str());
      throw;
    }
    description.path = label;
    description.band = band;
    state = qota::ShadowTiles(description, reader, frame).state();
  }
  return qota::ShadowTiles::restore(state);
}

// The light of every pixel of `tile` from the heights of `window` (the tile and its overlap), as
// qota shadow's raster values.
py::array_t<std::uint8_t> maskFromHeights(const qota::ShadowTiles& tiles, const Pixels& window, const Array& heights,
                                          const Pixels& tile, const std::array<double, 3>& light, unsigned threads) {
  const qota::PixelWindow w = pixelsOf(window), t = pixelsOf(tile);
  std::vector<double> z = heightsOf(heights, w);
  std::vector<qota::Light> mask;
  {
    py::gil_scoped_release release;
    mask = tiles.maskFromHeights(w, std::move(z), t, Eigen::Vector3d(light[0], light[1], light[2]), {}, threads);
  }
  py::array_t<std::uint8_t> out({t.height, t.width});
  std::uint8_t* o = out.mutable_data();
  for (std::size_t i = 0; i < mask.size(); ++i) {
    o[i] = mask[i] == qota::Light::Lit ? kLitValue : mask[i] == qota::Light::Shadow ? kShadowValue : kNoDataValue;
  }
  return out;
}

// Hours of sunlight of every pixel of `tile` (float32 with nodata, as qota shadow --hours writes
// them).
py::array_t<float> hoursFromHeights(const qota::ShadowTiles& tiles, const Pixels& window, const Array& heights,
                                    const Pixels& tile, double startJulianDay, double endJulianDay, double stepHours,
                                    const std::vector<std::array<double, 3>>& lights, unsigned threads) {
  const qota::PixelWindow w = pixelsOf(window), t = pixelsOf(tile);
  std::vector<double> z = heightsOf(heights, w);
  qota::SunlightHours hours;
  {
    py::gil_scoped_release release;
    hours = tiles.hoursFromHeights(w, std::move(z), t, startJulianDay, endJulianDay, stepHours, lightsOf(lights), {},
                                   qota::ShadowSearch::Strips, threads);
  }
  py::array_t<float> out({t.height, t.width});
  float* o = out.mutable_data();
  for (std::size_t i = 0; i < hours.hours.size(); ++i) {
    o[i] = hours.valid[i] ? static_cast<float>(hours.hours[i]) : kNoHours;
  }
  return out;
}

// The Sun seen from the tiles' centre at an instant: (azimuth, altitude) in degrees.
std::array<double, 2> sunAt(const qota::ShadowTiles& tiles, const std::string& time, const std::string& tz) {
  const qota::SunPosition sun =
      qota::sunOverFrame(tiles.frame(), qota::parseInstant(time, tz).julianDayUT, tiles.dem().path);
  return {sun.azimuth, sun.altitude};
}

// A raster's size, geotransform (and its inverse, GDAL's: pixel col, row = inverse applied to
// x, y), nodata and vertical unit (describeDem: nothing read but its header).
py::dict describeRaster(const std::string& path, int band) {
  qota::DemOptions options;
  options.band = band;
  options.lonLatAsCartesian = true;
  qota::DemTerrain dem;
  {
    py::gil_scoped_release release;
    dem = qota::describeDem(path, options);
  }
  py::dict d;
  d["width"] = dem.width;
  d["height"] = dem.height;
  d["geotransform"] = std::vector<double>(dem.geotransform.begin(), dem.geotransform.end());
  d["inverse_geotransform"] = dem.inverseGeotransform();
  d["nodata"] = dem.nodata ? py::object(py::float_(*dem.nodata)) : py::object(py::none());
  d["unit"] = dem.verticalUnit.name;
  return d;
}

// Every file GDAL reads for a raster: the file itself, a VRT's sources, sidecars (.aux.xml,
// .ovr, .msk, a world file). qota.dask watches them for a change between a call and its
// computation. Empty when GDAL cannot open the raster (reading it then says why).
std::vector<std::string> rasterFiles(const std::string& path) {
  py::gil_scoped_release release;
  qota::ensureGdalRegistered();
  CPLPushErrorHandler(CPLQuietErrorHandler);
  std::unique_ptr<GDALDataset> ds(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER));
  std::vector<std::string> files;
  if (ds) {
    char** list = ds->GetFileList();
    for (char** f = list; f && *f; ++f) files.emplace_back(*f);
    CSLDestroy(list);
  }
  ds.reset();
  CPLPopErrorHandler();
  return files;
}

// The instants (Julian days, UT) of the local clock hours start and end of a date (qota shadow
// --hours's span).
std::array<double, 2> localSpan(const std::string& time, const std::string& tz, double start, double end) {
  const qota::LocalSpan span = qota::localSpan(time, tz, start, end);
  return {span.start.julianDayUT, span.end.julianDayUT};
}

// A raster's heights under points, streamed: read tile by tile (RasterSampler), with the outer
// half-pixel rule as the Python Terrain and qota sample keep it (the whole terrain's answers, bit
// for bit), or by one of GDAL's rules (KernelSampler: nearest, bilinear, cubic). Points in the
// raster's CRS, or in `srs` (x easting/longitude, y northing/latitude). One sampler answers one
// batch at a time (its cache); others wait.
class Sampler {
 public:
  Sampler(const std::string& path, int band, const std::string& resampling, const std::string& srs) {
    const qota::Resampling rule = qota::resamplingNamed(resampling);
    py::gil_scoped_release release;
    if (rule == qota::Resampling::Triangle) {
      qota::RasterSampler::Options o;
      o.band = band;
      sampler_ = std::make_unique<qota::RasterSampler>(path, o);
    } else {
      kernel_ = std::make_unique<qota::KernelSampler>(path, band, rule);
    }
    const qota::DemTerrain& dem = this->dem();
    inverse_ = dem.inverseGeotransform();
    if (!srs.empty()) {
      if (dem.crsWkt.empty()) throw qota::Error(path + ": the raster has no CRS, so points in srs cannot be placed");
      transform_ = qota::transformTo(*qota::crsFromUser(srs, "srs"), dem.crsWkt,
                                     "srs '" + srs + "': no transformation to the raster's CRS");
    }
  }

  py::array_t<double> heights(const Array& x, const Array& y) {
    if (x.ndim() != 1 || y.ndim() != 1 || x.shape(0) != y.shape(0))
      throw qota::Error("x and y must be flat arrays of one length");
    const auto n = static_cast<std::size_t>(x.shape(0));
    std::vector<double> xs(x.data(), x.data() + n), ys(y.data(), y.data() + n);
    std::vector<std::optional<double>> answers(n);
    py::array_t<double> out(static_cast<py::ssize_t>(n));
    double* o = out.mutable_data();
    {
      py::gil_scoped_release release;
      const std::lock_guard<std::mutex> guard(lock_);
      if (transform_ && n > 0) {
        std::vector<int> ok(n);
        transform_->Transform(n, xs.data(), ys.data(), nullptr, ok.data());
        for (std::size_t i = 0; i < n; ++i) {
          if (!ok[i]) xs[i] = ys[i] = kNaN;  // not transformable: no terrain
        }
      }
      if (kernel_) {
        kernel_->heights(xs, ys, answers);
      } else {
        const qota::DemTerrain& dem = sampler_->dem();
        for (std::size_t i = 0; i < n; ++i) {
          const auto p = dem.surfacePoint(xs[i], ys[i], inverse_);
          xs[i] = p ? (*p)[0] : kNaN, ys[i] = p ? (*p)[1] : kNaN;  // off the raster: no terrain
        }
        sampler_->heights(xs, ys, {}, answers);
      }
      for (std::size_t i = 0; i < n; ++i) o[i] = answers[i] ? *answers[i] : kNaN;
    }
    return out;
  }

 private:
  const qota::DemTerrain& dem() const { return kernel_ ? kernel_->dem() : sampler_->dem(); }
  std::unique_ptr<qota::RasterSampler> sampler_;
  std::unique_ptr<qota::KernelSampler> kernel_;
  std::unique_ptr<OGRCoordinateTransformation> transform_;
  std::array<double, 6> inverse_{};
  std::mutex lock_;
};

}  // namespace

PYBIND11_MODULE(_qota, m) {
  m.doc() = "qota: terrain heights from rasters, arrays and meshes (Quick Oriented Terrain Algorithm)";
  m.attr("__version__") = QOTA_VERSION_STRING;
  // The mapping registry's names (qota/mapping_registry.hpp): qota.MAPPINGS.
  m.attr("MAPPINGS") = py::tuple(py::cast(qota::mappingNameList()));
  static py::exception<qota::Error> error(m, "Error", PyExc_ValueError);
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const qota::Error& e) {
      PyErr_SetString(error.ptr(), e.what());
    }
  });
  m.def("_shadow", &shadow, py::arg("dem"), py::arg("output"), py::arg("azimuth"), py::arg("altitude"), py::arg("time"),
        py::arg("tz"), py::arg("band"), py::arg("z_factor"), py::arg("hours") = py::none(), py::arg("height_ref") = "",
        py::arg("sun_vector") = py::none(), py::arg("sun_vector_body") = py::none(), py::arg("subsolar") = py::none(),
        py::arg("flat") = false, py::arg("png") = "");
  m.def("_viewshed", &viewshed, py::arg("dem"), py::arg("output"), py::arg("observer"), py::arg("srs"),
        py::arg("observer_height"), py::arg("target_height"), py::arg("max_distance"), py::arg("band"), py::arg("flat"),
        py::arg("height_ref"), py::arg("refraction") = 0.0);
  m.def("_cumulative", &cumulative, py::arg("path"), py::arg("x"), py::arg("y"), py::arg("heights"),
        py::arg("target_height"), py::arg("max_distance"), py::arg("band"), py::arg("flat"), py::arg("height_ref"));
  m.def("_sun_position", &sunPosition, py::arg("time"), py::arg("lon"), py::arg("lat"), py::arg("tz"));
  m.def("_write_raster", &writeRaster, py::arg("path"), py::arg("heights"), py::arg("transform"),
        py::arg("nodata") = py::none(), py::arg("crs") = "", py::arg("unit") = "");
  py::class_<qota::ShadowTiles>(m, "_ShadowTiles")
      .def_static("from_raster", &tilesFromRaster, py::arg("path"), py::arg("band"), py::arg("z_factor"))
      .def_static("from_reader", &tilesFromReader, py::arg("rows"), py::arg("cols"), py::arg("transform"),
                  py::arg("crs"), py::arg("unit"), py::arg("label"), py::arg("read"), py::arg("z_factor"),
                  py::arg("band") = 1)
      .def_property_readonly("width", [](const qota::ShadowTiles& t) { return t.dem().width; })
      .def_property_readonly("band", [](const qota::ShadowTiles& t) { return t.dem().band; })
      .def_property_readonly("z_factor", [](const qota::ShadowTiles& t) { return t.basis().options.zFactor; })
      .def_property_readonly("crs", [](const qota::ShadowTiles& t) { return t.dem().crsWkt; })
      .def_property_readonly("unit", [](const qota::ShadowTiles& t) { return t.dem().verticalUnit.name; })
      .def_property_readonly("source", [](const qota::ShadowTiles& t) { return t.dem().path; })
      .def_property_readonly("heights_hash",
                             [](const qota::ShadowTiles& t) { return qota::hexOf(t.heightBlocks().whole()); })
      .def_static(
          "bytes_per_window_pixel",
          [](const std::vector<std::array<double, 3>>& lights) {
            return qota::ShadowTiles::bytesPerWindowPixel(lightsOf(lights));
          },
          py::arg("lights"))
      .def(
          "largest_window_pixels",
          [](const qota::ShadowTiles& t, const std::vector<Pixels>& tiles,
             const std::vector<std::array<double, 3>>& lights) {
            std::vector<qota::PixelWindow> windows;
            for (const Pixels& c : tiles) windows.push_back(pixelsOf(c));
            return t.largestWindowPixels(windows, lightsOf(lights));
          },
          py::arg("tiles"), py::arg("lights"))
      .def(
          "checkable_window",
          [](const qota::ShadowTiles& t, const Pixels& w) {
            const qota::PixelWindow a = t.checkableWindow(pixelsOf(w));
            return Pixels{a.col, a.row, a.width, a.height};
          },
          py::arg("window"))
      .def_property_readonly("height", [](const qota::ShadowTiles& t) { return t.dem().height; })
      .def_property_readonly("geotransform", [](const qota::ShadowTiles& t) { return t.dem().geotransform; })
      .def("state", [](const qota::ShadowTiles& t) { return py::bytes(t.state()); })
      .def(
          "halo_for",
          [](const qota::ShadowTiles& t, int width, int height, const std::vector<std::array<double, 3>>& lights) {
            return t.haloFor(width, height, lightsOf(lights));
          },
          py::arg("width"), py::arg("height"), py::arg("lights"))
      .def(
          "toward_sun",
          [](const qota::ShadowTiles& t, double azimuth, double altitude) {
            const Eigen::Vector3d v = t.frame().towardSun({azimuth, altitude});
            return std::array<double, 3>{v.x(), v.y(), v.z()};
          },
          py::arg("azimuth"), py::arg("altitude"))
      .def("sun_at", &sunAt, py::arg("time"), py::arg("tz"))
      .def(
          "sunlight_steps",
          [](const qota::ShadowTiles& t, double start, double end, double step) {
            std::vector<std::array<double, 3>> out;
            for (const Eigen::Vector3d& v : t.sunlightSteps(start, end, step, t.horizonSlack()))
              out.push_back({v.x(), v.y(), v.z()});
            return out;
          },
          py::arg("start"), py::arg("end"), py::arg("step"))
      .def("mask_from_heights", &maskFromHeights, py::arg("window"), py::arg("heights"), py::arg("tile"),
           py::arg("light"), py::arg("threads") = 0)
      .def("hours_from_heights", &hoursFromHeights, py::arg("window"), py::arg("heights"), py::arg("tile"),
           py::arg("start"), py::arg("end"), py::arg("step"), py::arg("lights"), py::arg("threads") = 0)
      .def(py::pickle([](const qota::ShadowTiles& t) { return py::make_tuple(py::bytes(t.state())); },
                      [](const py::tuple& s) { return qota::ShadowTiles::restore(s[0].cast<std::string>()); }));
  m.def("_describe_raster", &describeRaster, py::arg("path"), py::arg("band"));
  m.def("_raster_files", &rasterFiles, py::arg("path"));
  m.def("_byte_size", &qota::tools::parseByteSize, py::arg("text"));
  m.def("_local_span", &localSpan, py::arg("time"), py::arg("tz"), py::arg("start"), py::arg("end"));
  m.def(
      "_check_hours", [](double start, double end, double step) { qota::checkHoursWindow(start, end, step, "hours"); },
      py::arg("start"), py::arg("end"), py::arg("step"));
  py::class_<Sampler>(m, "_RasterSampler")
      .def(py::init<const std::string&, int, const std::string&, const std::string&>(), py::arg("path"),
           py::arg("band"), py::arg("resampling") = "triangle", py::arg("srs") = "")
      .def("heights", &Sampler::heights, py::arg("x"), py::arg("y"));
  py::class_<Terrain>(m, "_Terrain")
      .def_static("from_raster", &fromRaster, py::arg("path"), py::arg("band"), py::arg("mapping"),
                  py::arg("radius") = py::none(), py::arg("length") = py::none(), py::arg("height_ref") = "",
                  py::arg("origin") = py::none())
      .def_static("from_array", &fromArray, py::arg("heights"), py::arg("transform"), py::arg("nodata") = py::none(),
                  py::arg("crs") = "", py::arg("unit") = "", py::arg("mapping") = "cartesian",
                  py::arg("radius") = py::none(), py::arg("length") = py::none(), py::arg("height_ref") = "",
                  py::arg("origin") = py::none())
      .def_static("from_mesh", &fromMesh, py::arg("vertices"), py::arg("triangles"), py::arg("mapping") = "cartesian",
                  py::arg("origin") = std::nullopt)
      .def_static("load", &load, py::arg("path"))
      .def("heights", &Terrain::heights)
      .def("below", &Terrain::below)
      .def("above", &Terrain::above)
      .def("all", &Terrain::all)
      .def("hits", &Terrain::hits, py::arg("x"), py::arg("y"), py::arg("z"), py::arg("mode"))
      .def("save", &Terrain::save)
      .def("stats", &Terrain::stats)
      .def_property_readonly("source", &Terrain::source)
      .def_property_readonly("mapping", &Terrain::mapping)
      .def_property_readonly("crs", &Terrain::crs)
      .def_property_readonly("height_ref", &Terrain::heightRef)
      .def_property_readonly("_lon_lat_map", &Terrain::lonLatMap);
}
