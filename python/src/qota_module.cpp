// qota._qota: the library's terrain index for numpy arrays. The Python side (python/qota/
// __init__.py) broadcasts and reshapes; here every call takes flat float64 arrays, answers with
// the library's parallel batches with the GIL released, and maps "no terrain" to NaN.
#include <gdal_priv.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <atomic>
#include <cmath>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <sstream>

#include "qota/batch.hpp"
#include "qota/dem.hpp"
#include "qota/error.hpp"
#include "qota/instant.hpp"
#include "qota/sun.hpp"
#include "qota/terrain.hpp"
#include "qota/treefile.hpp"
#include "qota/version.hpp"
#include "qota_tools.hpp"

namespace py = pybind11;

namespace {

using Array = py::array_t<double, py::array::c_style | py::array::forcecast>;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// A terrain in a Cartesian frame with gravity along -z: queries at world (x, y), heights in the
// source's own z. The index works in coordinates relative to its mapping's origin (near the
// data, for precision); the conversion is an exact subtraction.
class Terrain {
 public:
  Terrain(qota::TerrainIndex index, std::string source) : index_(std::move(index)), source_(std::move(source)) {}

  py::array_t<double> heights(const Array& x, const Array& y) const {
    return batch(x, y, nullptr, [&](auto pts, auto, auto out) { index_.heightsParallel(pts, out); });
  }
  py::array_t<double> below(const Array& x, const Array& y, const Array& z) const {
    return batch(x, y, &z, [&](auto pts, auto zs, auto out) { index_.heightsBelowParallel(pts, zs, out); });
  }
  py::array_t<double> above(const Array& x, const Array& y, const Array& z) const {
    // No batch for "above" in the library: one query a point, on this thread.
    return batch(x, y, &z, [&](auto pts, auto zs, auto out) {
      for (std::size_t i = 0; i < pts.size(); ++i) {
        const auto hit = index_.above(pts[i].u, pts[i].v, zs[i]);
        out[i] = hit ? std::optional(hit->height) : std::nullopt;
      }
    });
  }

  // The nearest hit below (or above) z at every point, with what it hit: heights (NaN: none),
  // polygon ids (-1: none) and unit normals (NaN: none), on every core with the GIL released.
  py::tuple hits(const Array& x, const Array& y, const Array& z, bool below) const {
    if (x.ndim() != 1 || y.ndim() != 1 || z.ndim() != 1 || x.shape(0) != y.shape(0) || z.shape(0) != x.shape(0)) {
      throw qota::Error("x, y and z must be flat arrays of one length");
    }
    const auto n = static_cast<std::size_t>(x.shape(0));
    py::array_t<double> heights(static_cast<py::ssize_t>(n));
    py::array_t<std::int64_t> polygons(static_cast<py::ssize_t>(n));
    py::array_t<double> normals({static_cast<py::ssize_t>(n), py::ssize_t{3}});
    const double *px = x.data(), *py_ = y.data(), *pz = z.data();
    double* h = heights.mutable_data();
    std::int64_t* p = polygons.mutable_data();
    double* nrm = normals.mutable_data();
    const Eigen::Vector3d o = index_.mapping().origin();
    {
      py::gil_scoped_release release;
      qota::batch::inSlices(n, 0, 4096, [&](std::size_t lo, std::size_t hi) {
        for (std::size_t i = lo; i < hi; ++i) {
          const double u = px[i] - o.x(), v = py_[i] - o.y(), w = pz[i] - o.z();
          const auto hit = below ? index_.below(u, v, w) : index_.above(u, v, w);
          h[i] = hit ? hit->height + o.z() : kNaN;
          p[i] = hit ? static_cast<std::int64_t>(hit->polygon) : -1;
          for (int k = 0; k < 3; ++k) nrm[3 * i + k] = hit ? hit->normal[k] : kNaN;
        }
      });
    }
    return py::make_tuple(heights, polygons, normals);
  }

  // Every surface on the vertical through (x, y), top first: (height, polygon id, normal).
  std::vector<py::tuple> all(double x, double y) const {
    const Eigen::Vector3d o = index_.mapping().origin();
    std::vector<py::tuple> out;
    for (const qota::Hit& h : index_.all(x - o.x(), y - o.y())) {
      out.push_back(py::make_tuple(h.height + o.z(), h.polygon,
                                   py::make_tuple(h.normal.x(), h.normal.y(), h.normal.z())));
    }
    return out;
  }

  void save(const std::string& path) const {
    qota::TreeSource source;
    source.path = source_;
    py::gil_scoped_release release;
    qota::saveTree(path, index_, source);
  }

  py::dict stats() const {
    const qota::IndexStats s = index_.stats();
    py::dict d;
    d["polygons"] = s.polygons;
    d["triangles"] = s.triangles;
    d["vertices"] = s.vertices;
    d["nodes"] = s.tree.nodes;
    d["memory_bytes"] = s.memoryBytes;
    return d;
  }

  const std::string& source() const { return source_; }

 private:
  template <class Run>
  py::array_t<double> batch(const Array& x, const Array& y, const Array* z, Run&& run) const {
    if (x.ndim() != 1 || y.ndim() != 1 || x.shape(0) != y.shape(0) || (z && (z->ndim() != 1 || z->shape(0) != x.shape(0)))) {
      throw qota::Error("x, y (and z) must be flat arrays of one length");
    }
    const std::size_t n = static_cast<std::size_t>(x.shape(0));
    const Eigen::Vector3d o = index_.mapping().origin();
    std::vector<qota::Point2> pts(n);
    std::vector<double> zs(z ? n : 0);  // per call: batches run with the GIL released
    std::vector<std::optional<double>> out(n);
    py::array_t<double> result(static_cast<py::ssize_t>(n));
    const double* px = x.data();
    const double* py_ = y.data();
    const double* pz = z ? z->data() : nullptr;
    double* r = result.mutable_data();
    {
      py::gil_scoped_release release;
      for (std::size_t i = 0; i < n; ++i) pts[i] = {px[i] - o.x(), py_[i] - o.y()};
      for (std::size_t i = 0; pz && i < n; ++i) zs[i] = pz[i] - o.z();
      run(std::span<const qota::Point2>(pts), std::span<const double>(zs), std::span<std::optional<double>>(out));
      for (std::size_t i = 0; i < n; ++i) r[i] = out[i] ? *out[i] + o.z() : kNaN;
    }
    return result;
  }

  qota::TerrainIndex index_;
  std::string source_;
};

qota::TerrainIndex indexOf(const qota::DemTerrain& dem) { return qota::TerrainIndex(dem.mesh, dem.mapping); }

Terrain fromRaster(const std::string& path, int band) {
  py::gil_scoped_release release;
  qota::DemOptions options;
  options.band = band;
  options.lonLatAsCartesian = true;  // heights at points, as gdallocationinfo: x, y in the CRS
  const qota::DemTerrain dem = qota::loadDem(path, options);
  return Terrain(indexOf(dem), path);
}

// A numpy array with a GDAL geotransform: written as a GeoTIFF in GDAL's memory file system and
// read back by loadDem, so the array's terrain is exactly the raster's (pixel centres, nodata
// holes, the outer half pixel).
Terrain fromArray(py::array_t<double, py::array::c_style | py::array::forcecast> heights,
                  const std::vector<double>& transform, std::optional<double> nodata) {
  if (heights.ndim() != 2 || heights.shape(0) < 1 || heights.shape(1) < 1) {
    throw qota::Error("heights must be a 2-D array (rows, columns) of at least one value");
  }
  if (transform.size() != 6) throw qota::Error("transform must have 6 numbers (GDAL's geotransform)");
  for (double t : transform) {
    if (!std::isfinite(t)) throw qota::Error("transform has a value that is not finite");
  }
  if (transform[1] * transform[5] - transform[2] * transform[4] == 0) {
    throw qota::Error("transform is singular (a pixel of zero area)");
  }
  const int rows = static_cast<int>(heights.shape(0)), cols = static_cast<int>(heights.shape(1));
  static std::atomic<unsigned> counter{0};
  const std::string path = "/vsimem/qota_python_" + std::to_string(counter++) + ".tif";
  const double* data = heights.data();
  py::gil_scoped_release release;
  qota::ensureGdalRegistered();
  {
    GDALDriver* gtiff = GetGDALDriverManager()->GetDriverByName("GTiff");
    std::unique_ptr<GDALDataset> ds(gtiff->Create(path.c_str(), cols, rows, 1, GDT_Float64, nullptr));
    if (!ds) throw qota::Error("cannot create the in-memory raster for the array");
    double gt[6];
    std::copy(transform.begin(), transform.end(), gt);
    ds->SetGeoTransform(gt);
    GDALRasterBand* b = ds->GetRasterBand(1);
    if (nodata) b->SetNoDataValue(*nodata);
    if (b->RasterIO(GF_Write, 0, 0, cols, rows, const_cast<double*>(data), cols, rows, GDT_Float64, 0, 0) != CE_None) {
      VSIUnlink(path.c_str());
      throw qota::Error("cannot write the array into the in-memory raster");
    }
  }
  try {
    qota::DemOptions options;
    options.lonLatAsCartesian = true;
    const qota::DemTerrain dem = qota::loadDem(path, options);
    VSIUnlink(path.c_str());
    return Terrain(indexOf(dem), "<array>");
  } catch (...) {
    VSIUnlink(path.c_str());
    throw;
  }
}

Terrain fromMesh(py::array_t<double, py::array::c_style | py::array::forcecast> vertices,
                 py::array_t<std::int64_t, py::array::c_style | py::array::forcecast> triangles) {
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
      throw qota::Error("triangle " + std::to_string(k / 3) + " names vertex " + std::to_string(t[k]) + ", not one of the " +
                        std::to_string(n) + " vertices");
    }
    mesh.indices.push_back(static_cast<std::uint32_t>(t[k]));
  }
  if (n == 0 || m == 0) throw qota::Error("the mesh has no triangles");
  // The origin at the centre of the footprint (z 0, so heights stay in the mesh's own z).
  const Eigen::Vector3d origin(0.5 * (lo.x() + hi.x()), 0.5 * (lo.y() + hi.y()), 0.0);
  return Terrain(qota::TerrainIndex(mesh, qota::CartesianMapping({0, 0, -1}, origin)), "<mesh>");
}

Terrain load(const std::string& path) {
  qota::TreeFile tf = [&] {
    py::gil_scoped_release release;
    return qota::loadTree(path);
  }();
  auto* index = std::get_if<qota::TerrainIndex>(&tf.index);
  if (!index || !index->mapping().vertical()) {
    throw qota::Error(path + ": not a Cartesian terrain with vertical gravity (the Python package reads those)");
  }
  return Terrain(std::move(*index), tf.source.path);
}

// qota shadow itself (the same cells, the same checks and messages), into `output`, read back.
py::array_t<std::uint8_t> shadow(const std::string& dem, const std::string& output, std::optional<double> azimuth,
                                 std::optional<double> altitude, const std::string& time, const std::string& tz,
                                 int band, double zFactor) {
  qota::tools::ShadowOptions o;
  o.source = dem;
  o.output = output;
  o.quiet = true;
  o.band = band;
  o.azimuth = azimuth;
  o.altitude = altitude;
  o.time = time;
  o.tz = tz;
  o.zFactor = zFactor;
  std::ostringstream out, err;
  int code = 0;
  {
    py::gil_scoped_release release;
    code = qota::tools::shadow(o, out, err);
  }
  if (code != 0) {
    std::string message = err.str();
    while (!message.empty() && message.back() == '\n') message.pop_back();
    throw qota::Error(message.empty() ? "qota shadow failed" : message);
  }
  qota::ensureGdalRegistered();
  std::unique_ptr<GDALDataset> ds(GDALDataset::Open(output.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
  if (!ds) throw qota::Error(output + ": cannot read the shadow raster back");
  const int w = ds->GetRasterXSize(), h = ds->GetRasterYSize();
  py::array_t<std::uint8_t> mask({h, w});
  if (ds->GetRasterBand(1)->RasterIO(GF_Read, 0, 0, w, h, mask.mutable_data(), w, h, GDT_Byte, 0, 0) != CE_None) {
    throw qota::Error(output + ": cannot read the shadow raster back");
  }
  return mask;
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

}  // namespace

PYBIND11_MODULE(_qota, m) {
  m.doc() = "qota: terrain heights from rasters, arrays and meshes (Quick Oriented Terrain Algorithm)";
  m.attr("__version__") = QOTA_VERSION_STRING;
  static py::exception<qota::Error> error(m, "Error", PyExc_ValueError);
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const qota::Error& e) {
      PyErr_SetString(error.ptr(), e.what());
    }
  });
  m.def("_shadow", &shadow, py::arg("dem"), py::arg("output"), py::arg("azimuth"), py::arg("altitude"),
        py::arg("time"), py::arg("tz"), py::arg("band"), py::arg("z_factor"));
  m.def("_sun_position", &sunPosition, py::arg("time"), py::arg("lon"), py::arg("lat"), py::arg("tz"));
  py::class_<Terrain>(m, "_Terrain")
      .def_static("from_raster", &fromRaster, py::arg("path"), py::arg("band") = 0)
      .def_static("from_array", &fromArray, py::arg("heights"), py::arg("transform"), py::arg("nodata") = py::none())
      .def_static("from_mesh", &fromMesh, py::arg("vertices"), py::arg("triangles"))
      .def_static("load", &load, py::arg("path"))
      .def("heights", &Terrain::heights)
      .def("below", &Terrain::below)
      .def("above", &Terrain::above)
      .def("all", &Terrain::all)
      .def("hits", &Terrain::hits)
      .def("save", &Terrain::save)
      .def("stats", &Terrain::stats)
      .def_property_readonly("source", &Terrain::source);
}
