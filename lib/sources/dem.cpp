#include "qota/dem.hpp"

#include <cpl_error.h>
#include <gdal_alg.h>
#include <gdal_priv.h>
#include <ogr_spatialref.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <limits>
#include <memory>
#include <mutex>
#include <sstream>
#include <vector>

#include "gdal_errors.hpp"
#include "qota/error.hpp"
#include "qota/raster_grid.hpp"
#include "qota/terrain.hpp"

namespace qota {
namespace {

using detail::gdalMessage;
using detail::QuietGdalErrors;

}  // namespace

void ensureGdalRegistered() {
  static std::once_flag once;
  std::call_once(once, [] { GDALAllRegister(); });
}

std::array<double, 6> DemTerrain::inverseGeotransform() const {
  double gt[6], inv[6];
  std::copy(geotransform.begin(), geotransform.end(), gt);
  if (!GDALInvGeoTransform(gt, inv)) return {NAN, NAN, NAN, NAN, NAN, NAN};
  return {inv[0], inv[1], inv[2], inv[3], inv[4], inv[5]};
}

std::array<double, 2> DemTerrain::pixelOf(double x, double y) const { return pixelOf(x, y, inverseGeotransform()); }

bool DemTerrain::onRaster(double x, double y) const {
  const auto [col, row] = pixelOf(turnedOnto(x), y);
  return col >= 0 && col <= width && row >= 0 && row <= height;
}

namespace {

constexpr double kMaxCoordinate = 1e100, kMinPixelArea = 1e-200, kMaxPixelAspect = 1e6;

std::string lowerTrimmed(const std::string& text) {
  std::size_t a = 0, b = text.size();
  while (a < b && std::isspace(static_cast<unsigned char>(text[a]))) ++a;
  while (b > a && std::isspace(static_cast<unsigned char>(text[b - 1]))) --b;
  std::string s = text.substr(a, b - a);
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

// The band's unit type, else the unit of a vertical CRS (alone or in a compound CRS).
VerticalUnit verticalUnitOf(const std::string& path, GDALRasterBand* band, const OGRSpatialReference* srs) {
  VerticalUnit unit;
  const char* type = band->GetUnitType();
  if (type && *type) {
    const std::optional<double> m = metresPerLengthUnit(type);
    if (!m) {
      throw Error(path + ": band " + std::to_string(band->GetBand()) + " has unit type '" + type +
                  "', which is not a length; its values are not heights (give -z/--z-factor to "
                  "say how many metres one unit is)");
    }
    unit.name = type;
    unit.metresPerUnit = *m;
    return unit;
  }
  if (srs && (srs->IsCompound() || srs->IsVertical())) {
    const char* name = nullptr;
    const double m = srs->GetTargetLinearUnits("VERT_CS", &name);
    if (m > 0 && std::isfinite(m)) {
      unit.name = name && *name ? name : "metre";
      unit.metresPerUnit = m;
    }
  }
  return unit;
}

VerticalReference verticalReferenceOf(const OGRSpatialReference* srs) {
  VerticalReference v;
  if (!srs) return v;
  OGRErr e = OGRERR_NONE;
  const double a = srs->GetSemiMajor(&e);
  // The Earth's ellipsoids all have a semi-major axis within a few kilometres of 6378 km.
  v.earth = e != OGRERR_NONE || (a > 6.36e6 && a < 6.39e6);
  if (srs->IsCompound() || srs->IsVertical()) {
    const char* name = srs->GetAttrValue("VERT_CS");
    v.name = name && *name ? name : "a vertical CRS";
    const char* code = srs->GetAuthorityCode("VERT_CS");
    const char* authority = srs->GetAuthorityName("VERT_CS");
    if (code && authority && std::string(authority) == "EPSG") v.epsg = std::atoi(code);
  } else if (srs->IsGeographic() && srs->GetAxesCount() == 3) {
    v.ellipsoidal = true;
  }
  return v;
}

// A geotransform that places pixels usably: finite, invertible, with pixel sizes and an extent
// whose products stay in the range of doubles (the exact predicates multiply coordinate
// differences: 1e-300 m pixels or 1e300 m rasters would underflow or overflow them).
void checkGeotransform(const std::string& path, const std::array<double, 6>& g, int width, int height) {
  const auto text = [&] {
    std::ostringstream s;
    s.precision(17);
    s << g[0] << ", " << g[1] << ", " << g[2] << ", " << g[3] << ", " << g[4] << ", " << g[5];
    return s.str();
  };
  for (double x : g) {
    if (!std::isfinite(x) || std::fabs(x) > kMaxCoordinate) {
      throw Error(path + ": geotransform (" + text() + ") is not finite or beyond 1e100");
    }
  }
  const double det = g[1] * g[5] - g[2] * g[4];
  if (!(std::fabs(det) >= kMinPixelArea)) {
    throw Error(path + ": geotransform (" + text() +
                ") gives pixels of no area (or below 1e-200): "
                "they cannot be placed");
  }
  // Pixels a million times longer one way than the other, or sheared flat, are a broken
  // geotransform (real rasters stay within a few hundred): their triangles would be slivers whose
  // every overlap test falls to exact arithmetic (seconds a thousand pixels).
  const double stepCol = std::hypot(g[1], g[4]), stepRow = std::hypot(g[2], g[5]);
  const double aspect = std::max(stepCol, stepRow) / std::min(stepCol, stepRow);
  const double area = std::fabs(det) / (stepCol * stepRow);  // 1 for rectangular pixels
  if (!(aspect <= kMaxPixelAspect) || !(area >= 1 / kMaxPixelAspect)) {
    std::ostringstream what;
    what << path << ": geotransform (" << text() << ") gives pixels " << std::setprecision(3);
    if (!(aspect <= kMaxPixelAspect)) {
      what << aspect << " times as long one way as the other";
    } else {
      what << "sheared to " << area << " of a rectangle's area";
    }
    what << " (beyond 1e6): check its pixel sizes and rotation terms";
    throw Error(what.str());
  }
  const double w = width, h = height;
  if (std::fabs(g[0]) + w * std::fabs(g[1]) + h * std::fabs(g[2]) > kMaxCoordinate ||
      std::fabs(g[3]) + w * std::fabs(g[4]) + h * std::fabs(g[5]) > kMaxCoordinate) {
    throw Error(path + ": geotransform (" + text() + ") puts the raster beyond 1e100");
  }
}

// Opens the raster and reads its description (no pixels). ds receives the dataset.
DemTerrain openDem(const std::string& path, const DemOptions& options, std::unique_ptr<GDALDataset>& ds,
                   GDALRasterBand*& band) {
  ensureGdalRegistered();
  QuietGdalErrors quiet;
  ds.reset(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY | GDAL_OF_VERBOSE_ERROR));
  if (!ds) throw Error(path + ": cannot open as a raster" + gdalMessage());
  const int bands = ds->GetRasterCount();
  if (options.band == 0 && bands != 1) {
    throw Error(path + ": has " + std::to_string(bands) +
                " bands; choose the one that holds the "
                "heights (-b N, DemOptions::band)");
  }
  const int b = options.band == 0 ? 1 : options.band;
  if (b < 1 || b > bands) {
    throw Error(path + ": has " + std::to_string(bands) + " band(s), no band " + std::to_string(b));
  }
  band = ds->GetRasterBand(b);

  DemTerrain dem;
  dem.path = path;
  dem.band = b;
  dem.driver = ds->GetDriver() ? ds->GetDriver()->GetDescription() : "";
  dem.width = ds->GetRasterXSize();
  dem.height = ds->GetRasterYSize();
  if (dem.width < 2 || dem.height < 2) {
    // Vertices are the pixel centres: one row or column of them spans no triangle, so there
    // would be no surface to answer on, not even at the pixels' own centres.
    throw Error(path + ": a raster of " + std::to_string(dem.width) + " x " + std::to_string(dem.height) +
                " pixels; its pixel centres make no surface (qota needs at least 2 x 2 pixels)");
  }
  double gt[6];
  if (ds->GetGeoTransform(gt) == CE_None) std::copy(gt, gt + 6, dem.geotransform.begin());
  checkGeotransform(path, dem.geotransform, dem.width, dem.height);
  const OGRSpatialReference* srs = ds->GetSpatialRef();
  if (srs) {
    char* wkt = nullptr;
    if (srs->exportToWkt(&wkt) == OGRERR_NONE && wkt) dem.crsWkt = wkt;
    CPLFree(wkt);
  }
  int hasNodata = 0;
  const double nodata = band->GetNoDataValue(&hasNodata);
  if (hasNodata) dem.nodata = nodata;
  {
    int hasScale = FALSE, hasOffset = FALSE;
    const double scale = band->GetScale(&hasScale), offset = band->GetOffset(&hasOffset);
    dem.integerValues = !GDALDataTypeIsFloating(band->GetRasterDataType()) &&
                        !GDALDataTypeIsComplex(band->GetRasterDataType()) && (!hasScale || scale == 1) &&
                        (!hasOffset || offset == 0);
  }
  dem.verticalUnit = verticalUnitOf(path, band, srs);
  dem.verticalReference = verticalReferenceOf(srs);
  dem.lonLat = srs && srs->IsGeographic() && dem.geotransform[2] == 0 && dem.geotransform[4] == 0;
  if (!options.lonLatAsCartesian && srs && srs->IsGeographic()) {
    throw Error(path +
                ": the raster is in longitude/latitude degrees, so as a Cartesian terrain "
                "its x and y would be degrees and its heights metres, and slopes, normals and "
                "poses would be wrong; put it on its ellipsoid (loadOnEllipsoid, --mapping "
                "geodetic), reproject it (gdalwarp -t_srs EPSG:326..), or set "
                "DemOptions::lonLatAsCartesian when only heights at points are wanted");
  }
  return dem;
}

// A raw band value's height: the band's scale and offset applied; NaN for none (the nodata
// value, NaN or infinite, or a scale that overflows).
struct HeightRule {
  bool hasNodata = false, rescale = false;
  int hasScale = 0, hasOffset = 0;
  double nodata = 0, scale = 1, offset = 0;

  HeightRule(GDALRasterBand* band, const DemTerrain& dem)
      : hasNodata(dem.nodata.has_value()), nodata(dem.nodata.value_or(0.0)) {
    scale = band->GetScale(&hasScale), offset = band->GetOffset(&hasOffset);
    rescale = (hasScale && scale != 1.0) || (hasOffset && offset != 0.0);
  }
  double operator()(double value) const {
    bool ok = std::isfinite(value) && !(hasNodata && value == nodata);
    if (ok && rescale) {
      value = value * (hasScale ? scale : 1.0) + (hasOffset ? offset : 0.0);
      ok = std::isfinite(value);  // a scale can overflow: no height, not infinity
    }
    return ok ? value : NAN;
  }
};

// Reads pixels [col, col + w) x [row, row + h) of the band as heights (NaN: none), row-major.
void readHeights(const DemTerrain& dem, GDALRasterBand* band, int col, int row, int w, int h,
                 std::vector<double>& out) {
  out.resize(static_cast<std::size_t>(w) * h);
  if (out.empty()) return;
  QuietGdalErrors quiet;
  if (band->RasterIO(GF_Read, col, row, w, h, out.data(), w, h, GDT_Float64, 0, 0) != CE_None) {
    throw Error(dem.path + ": cannot read band " + std::to_string(dem.band) + gdalMessage());
  }
  const HeightRule rule(band, dem);
  for (double& z : out) z = rule(z);
}

}  // namespace

bool crsIsGeographic(const std::string& wkt) {
  if (wkt.empty()) return false;
  OGRSpatialReference srs;
  QuietGdalErrors quiet;
  return srs.importFromWkt(wkt.c_str()) == OGRERR_NONE && srs.IsGeographic();
}

std::optional<double> metresPerLengthUnit(const std::string& unitText) {
  const std::string u = lowerTrimmed(unitText);
  if (u == "m" || u == "metre" || u == "meter" || u == "metres" || u == "meters") return 1.0;
  if (u == "ft" || u == "foot" || u == "feet" || u == "international foot" || u == "foot (international)" ||
      u == "ft (international)") {
    return 0.3048;
  }
  if (u == "us survey foot" || u == "us-ft" || u == "ftus" || u == "us_survey_foot" || u == "foot_us" ||
      u == "us foot" || u == "survey foot" || u == "ft_us" || u == "us survey feet") {
    return 1200.0 / 3937.0;
  }
  if (u == "cm" || u == "centimetre" || u == "centimeter") return 0.01;
  if (u == "mm" || u == "millimetre" || u == "millimeter") return 0.001;
  if (u == "dm" || u == "decimetre" || u == "decimeter") return 0.1;
  if (u == "km" || u == "kilometre" || u == "kilometer") return 1000.0;
  return std::nullopt;
}

std::optional<std::array<double, 2>> DemTerrain::surfacePoint(double x, double y) const {
  return surfacePoint(x, y, inverseGeotransform());
}

double DemTerrain::turnedOnto(double x) const {
  if (!lonLat || !std::isfinite(x)) return x;
  const auto& g = geotransform;
  const double west = std::min(g[0], g[0] + width * g[1]), east = std::max(g[0], g[0] + width * g[1]);
  if (x >= west && x <= east) return x;
  const double turned = x + 360.0 * std::round((0.5 * (west + east) - x) / 360.0);
  return turned >= west && turned <= east ? turned : x;
}

std::optional<std::array<double, 2>> DemTerrain::surfacePoint(double x, double y,
                                                              const std::array<double, 6>& inverse) const {
  x = turnedOnto(x);
  const auto [col, row] = pixelOf(x, y, inverse);
  if (!(col >= 0 && col <= width && row >= 0 && row <= height)) return std::nullopt;
  const double c = std::clamp(col, 0.5, width - 0.5), r = std::clamp(row, 0.5, height - 0.5);
  if (c == col && r == row) return std::array<double, 2>{x, y};
  // pixelCentre's arithmetic, so a clamped coordinate equals the vertices' bit for bit.
  return pixelCentre(c - 0.5, r - 0.5);
}

CartesianMapping DemTerrain::centredMapping() const {
  const auto centre = pixelCentre((width - 1) / 2.0, (height - 1) / 2.0);
  return CartesianMapping(Eigen::Vector3d(0, 0, -1), Eigen::Vector3d(centre[0], centre[1], 0));
}

struct DemWindows::Open {
  std::unique_ptr<GDALDataset> ds;
  GDALRasterBand* band = nullptr;
};

DemWindows::DemWindows(const std::string& path, const DemOptions& options) : open_(std::make_unique<Open>()) {
  dem_ = openDem(path, options, open_->ds, open_->band);
  dem_.mapping = dem_.centredMapping();
}

DemWindows::~DemWindows() = default;

void DemWindows::read(int col, int row, int w, int h, std::vector<double>& out) const {
  if (col < 0 || row < 0 || w < 0 || h < 0 || col + w > dem_.width || row + h > dem_.height) {
    throw Error(dem_.path + ": window (" + std::to_string(col) + ", " + std::to_string(row) + ") + (" +
                std::to_string(w) + " x " + std::to_string(h) + ") is not on the raster");
  }
  readHeights(dem_, open_->band, col, row, w, h, out);
}

namespace {

// GDAL's fill-nodata over heights in memory (NaN: a void), searching maxDistance pixels out.
// Returns the voids filled.
std::uint64_t fillVoidsLikeGdal(std::vector<double>& z, int width, int height, double maxDistance,
                                const std::string& path) {
  const std::uint64_t before =
      static_cast<std::uint64_t>(std::count_if(z.begin(), z.end(), [](double v) { return std::isnan(v); }));
  if (before == 0) return 0;
  GDALDriver* mem = GetGDALDriverManager()->GetDriverByName("MEM");
  std::unique_ptr<GDALDataset> ds(mem ? mem->Create("", width, height, 1, GDT_Float64, nullptr) : nullptr);
  if (!ds) throw Error(path + ": cannot hold the heights to fill their voids");
  GDALRasterBand* band = ds->GetRasterBand(1);
  band->SetNoDataValue(std::numeric_limits<double>::quiet_NaN());
  if (band->RasterIO(GF_Write, 0, 0, width, height, z.data(), width, height, GDT_Float64, 0, 0) != CE_None ||
      GDALFillNodata(band, nullptr, maxDistance, 0, 0, nullptr, nullptr, nullptr) != CE_None ||
      band->RasterIO(GF_Read, 0, 0, width, height, z.data(), width, height, GDT_Float64, 0, 0) != CE_None) {
    throw Error(path + ": filling the voids failed (" + std::string(CPLGetLastErrorMsg()) + ")");
  }
  const std::uint64_t after =
      static_cast<std::uint64_t>(std::count_if(z.begin(), z.end(), [](double v) { return std::isnan(v); }));
  return before - after;
}

}  // namespace

DemTerrain describeDem(const std::string& path, const DemOptions& options) {
  std::unique_ptr<GDALDataset> ds;
  GDALRasterBand* band = nullptr;
  return openDem(path, options, ds, band);
}

DemTerrain loadDem(const std::string& path, const DemOptions& options) {
  std::unique_ptr<GDALDataset> ds;
  GDALRasterBand* band = nullptr;
  DemTerrain dem = openDem(path, options, ds, band);
  QuietGdalErrors quiet;

  // Refuse what cannot fit before allocating: the raster as doubles, the mesh, and the index.
  const std::uint64_t w = static_cast<std::uint64_t>(dem.width);
  const std::uint64_t h = static_cast<std::uint64_t>(dem.height);
  const std::uint64_t vertices = w * h;
  const std::uint64_t triangles = w > 1 && h > 1 ? 2 * (w - 1) * (h - 1) : 0;
  const memory::PerItem read = options.vertices ? memory::kDemMesh : memory::kDemHeights;
  const memory::PerItem then = dem.crsWkt.empty() ? options.thenWithoutCrs.value_or(options.then) : options.then;
  const std::uint64_t need = memory::kProcessBase + read.bytes(vertices, triangles) + then.bytes(vertices, triangles);
  dem.estimatedBytes = need;
  const std::uint64_t limit = options.memoryLimitBytes ? options.memoryLimitBytes : memory::availableBytes();
  if (vertices >= 0xffffffffull || (limit && need > limit)) {
    throw Error(path + ": a " + std::to_string(dem.width) + " x " + std::to_string(dem.height) +
                " raster needs about " + memory::gib(need) + " for this job, more than the " + memory::gib(limit) +
                " of memory available; cut it into tiles (gdal_translate -srcwin) "
                "or resample it");
  }

  std::vector<double> z;
  readHeights(dem, band, 0, 0, dem.width, dem.height, z);
  if (options.fillVoids > 0) dem.filledPixels = fillVoidsLikeGdal(z, dem.width, dem.height, options.fillVoids, path);

  if (!options.vertices) {
    for (const double v : z) dem.nodataPixels += std::isnan(v);
    dem.heights = std::move(z);
    dem.mapping = dem.centredMapping();
    return dem;
  }
  // Vertices: every pixel centre; a nodata pixel gets NaN height and no triangle uses it.
  std::vector<std::uint8_t> valid(vertices);
  dem.mesh.vertices.resize(vertices);
  for (std::uint64_t r = 0; r < h; ++r) {
    for (std::uint64_t c = 0; c < w; ++c) {
      const std::uint64_t i = r * w + c;
      valid[i] = !std::isnan(z[i]);
      dem.nodataPixels += !valid[i];
      const auto xy = dem.pixelCentre(static_cast<double>(c), static_cast<double>(r));
      dem.mesh.vertices[i] = Eigen::Vector3d(xy[0], xy[1], z[i]);
    }
  }
  std::vector<double>().swap(z);

  // The grid's triangles (raster_grid.hpp), none with a nodata corner.
  if (options.triangles) {
    RasterGrid(dem.width, dem.height, {}).appendTriangles(dem.mesh, [&](std::uint32_t i) { return valid[i] != 0; });
  }

  dem.mapping = dem.centredMapping();
  return dem;
}

}  // namespace qota
