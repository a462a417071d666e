// Vertical references and geoid grids (see qota/geoid.hpp).
#include "qota/geoid.hpp"

#include <gdal_priv.h>
#include <ogr_spatialref.h>
#include <proj.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <limits>

#include "gdal_errors.hpp"
#include "qota/error.hpp"
#include "qota/globe.hpp"

namespace qota {
namespace {

namespace fs = std::filesystem;

struct KnownGeoid {
  const char* word;      // the option's word
  const char* name;      // as said
  int verticalEpsg;      // the vertical CRS of heights over it
  const char* files[2];  // the grid's names in PROJ's data (old and new)
  const char* fetch;     // how to get it when it is not there
};

constexpr KnownGeoid kGeoids[] = {
    {"egm96",
     "EGM96 geoid",
     5773,
     {"egm96_15.gtx", "us_nga_egm96_15.tif"},
     "install Debian's proj-data (apt-get install proj-data), or `projsync --file us_nga_egm96_15.tif`"},
    {"egm2008",
     "EGM2008 geoid",
     3855,
     {"us_nga_egm08_25.tif", "egm08_25.gtx"},
     "it is not packaged in Debian: `projsync --file us_nga_egm08_25.tif` fetches it into PROJ's user folder, "
     "or give the path of a copy (--height-ref /path/us_nga_egm08_25.tif)"},
};

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

// The folders PROJ looks for grids in: PROJ_DATA (or PROJ_LIB), PROJ's user folder and its own.
std::vector<fs::path> projFolders() {
  std::vector<fs::path> out;
  for (const char* var : {"PROJ_DATA", "PROJ_LIB"}) {
    if (const char* v = std::getenv(var)) {
      std::string s = v;
      for (std::size_t start = 0; start <= s.size();) {
        const std::size_t end = std::min(s.find(':', start), s.size());
        if (end > start) out.emplace_back(s.substr(start, end - start));
        start = end + 1;
      }
    }
  }
  if (const char* user = proj_context_get_user_writable_directory(nullptr, 0)) out.emplace_back(user);
  const PJ_INFO info = proj_info();
  if (info.searchpath) {
    const std::string s = info.searchpath;
    for (std::size_t start = 0; start <= s.size();) {
      const std::size_t end = std::min(s.find(';', start), s.size());
      if (end > start) out.emplace_back(s.substr(start, end - start));
      start = end + 1;
    }
  }
  out.emplace_back("/usr/share/proj");
  return out;
}

std::string findGrid(const KnownGeoid& g) {
  for (const fs::path& folder : projFolders()) {
    for (const char* file : g.files) {
      std::error_code ec;
      if (fs::is_regular_file(folder / file, ec)) return (folder / file).string();
    }
  }
  return {};
}

HeightReference geoid(const KnownGeoid& g, const std::string& why, const std::string& path) {
  HeightReference r;
  r.name = g.name;
  r.grid = findGrid(g);
  r.why = why;
  if (r.grid.empty()) {
    throw Error(path + ": heights over the " + std::string(g.name) + " (" + why + ") need its grid " + g.files[0] +
                ", which PROJ does not have here: " + g.fetch);
  }
  return r;
}

HeightReference ellipsoid(const std::string& why) {
  HeightReference r;
  r.why = why;
  return r;
}

}  // namespace

std::string HeightReference::describe() const {
  std::string s = name;
  if (!grid.empty() && grid.rfind("radius:", 0) != 0) s += " (" + fs::path(grid).filename().string() + ")";
  if (!why.empty()) s += "; " + why;
  return s;
}

HeightReference heightReferenceOf(const DemTerrain& dem, const std::string& askedText) {
  const std::string asked = lower(askedText);
  if (asked == "ellipsoid") return ellipsoid("asked (--height-ref ellipsoid)");
  for (const KnownGeoid& g : kGeoids) {
    if (asked == g.word) return geoid(g, std::string("asked (--height-ref ") + g.word + ")", dem.path);
  }
  if (asked.rfind("radius:", 0) == 0) {
    // Over a sphere of radius R: on a spherical body (the CRS's ellipsoid a sphere), a constant
    // undulation R - a; on a flattened one the sphere's heights run along radii, not normals: the
    // spherical mapping takes them as they are.
    char* end = nullptr;
    const double radius = std::strtod(asked.c_str() + 7, &end);
    if (end == asked.c_str() + 7 || *end || !(radius > 0 && radius < 1e9)) {
      throw Error("--height-ref '" + askedText + "': radius:R takes a radius in metres (radius:3396000)");
    }
    double a = 0, f = 0;
    demEllipsoid(dem, a, f);
    if (f != 0) {
      throw Error(dem.path + ": --height-ref " + askedText +
                  " (heights over a sphere) on a flattened ellipsoid: a "
                  "sphere's heights run along its radii; take them with --mapping spherical --radius " +
                  askedText.substr(7));
    }
    HeightReference r;
    r.name = "sphere of radius " + askedText.substr(7) + " m";
    r.grid = "radius:" + askedText.substr(7) + ":" + std::to_string(radius - a);
    r.why = "asked (--height-ref " + askedText + ")";
    return r;
  }
  if (!asked.empty() && asked != "crs") {
    std::error_code ec;
    if (!fs::is_regular_file(askedText, ec) && askedText.rfind("/vsi", 0) != 0) {
      throw Error("--height-ref '" + askedText + "': not one of " + kHeightRefChoices + " (no such file)");
    }
    HeightReference r;
    r.name = fs::path(askedText).filename().string();
    r.grid = askedText;
    r.why = "asked (--height-ref " + askedText + ")";
    return r;
  }
  // The raster's own.
  const VerticalReference& v = dem.verticalReference;
  if (v.ellipsoidal) return ellipsoid("stated by its three-dimensional CRS");
  if (!v.name.empty()) {
    for (const KnownGeoid& g : kGeoids) {
      if (v.epsg == g.verticalEpsg) {
        return geoid(g, "stated by its vertical CRS " + v.name + " (EPSG:" + std::to_string(v.epsg) + ")", dem.path);
      }
    }
    throw Error(dem.path + ": its vertical CRS is " + v.name +
                (v.epsg ? " (EPSG:" + std::to_string(v.epsg) + ")" : "") +
                ", whose geoid grid qota does not know; give --height-ref with the grid's path, or " +
                "--height-ref ellipsoid if the heights are over the ellipsoid");
  }
  if (asked == "crs") {
    throw Error(dem.path + ": --height-ref crs, but the raster states no vertical CRS; give one of " +
                std::string(kHeightRefChoices));
  }
  const std::string assumed = "assumed: the raster states no vertical reference; give --height-ref to say it";
  HeightReference r = dem.verticalReference.earth ? geoid(kGeoids[0], assumed, dem.path) : ellipsoid(assumed);
  r.assumed = true;
  return r;
}

HeightReference storedHeightReference(const std::string& name, const std::string& grid) {
  HeightReference r;
  r.why = "as recorded";
  if (grid.empty()) return r;
  r.name = name;
  if (grid.rfind("radius:", 0) == 0) {
    r.grid = grid;
    return r;
  }
  std::error_code ec;
  if (fs::is_regular_file(grid, ec)) {
    r.grid = grid;
    return r;
  }
  const fs::path file = fs::path(grid).filename();
  for (const fs::path& folder : projFolders()) {
    if (fs::is_regular_file(folder / file, ec)) {
      r.grid = (folder / file).string();
      return r;
    }
  }
  throw Error("heights over the " + name + " need its grid " + file.string() + ", which is not found here (" + grid +
              ", nor in PROJ's folders)");
}

Geoid::Geoid(const HeightReference& reference) {
  if (reference.ellipsoidal()) return;
  path_ = reference.grid;
  read(std::nullopt);
}

Geoid::Geoid(const HeightReference& reference, const std::array<double, 4>& lonLatBox) {
  if (reference.ellipsoidal()) return;
  path_ = reference.grid;
  read(lonLatBox);
}

void Geoid::read(const std::optional<std::array<double, 4>>& box) {
  if (path_.rfind("radius:", 0) == 0) {  // "radius:R:R-a"
    constant_ = std::strtod(path_.c_str() + path_.rfind(':') + 1, nullptr);
    if (constant_ == 0) constant_ = std::numeric_limits<double>::denorm_min();  // (a sphere of radius a: still said)
    return;
  }
  ensureGdalRegistered();
  detail::GdalErrorLog errors;
  std::unique_ptr<GDALDataset> ds(GDALDataset::Open(path_.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
  if (!ds) throw Error(path_ + ": cannot read the geoid grid (" + errors.reason() + ")");
  double gt[6];
  if (ds->GetGeoTransform(gt) != CE_None || gt[2] != 0 || gt[4] != 0 || !(gt[1] > 0) || gt[5] == 0) {
    throw Error(path_ + ": a geoid grid must be a north-up grid over longitude/latitude");
  }
  width_ = ds->GetRasterXSize(), height_ = ds->GetRasterYSize();
  if (width_ < 2 || height_ < 2 || static_cast<double>(width_) * height_ > 4e8) {
    throw Error(path_ + ": a geoid grid of " + std::to_string(width_) + " x " + std::to_string(height_) + " nodes");
  }
  // Nodes at the pixel centres (GDAL's reading of node grids such as GTX).
  dlon_ = gt[1], dlat_ = gt[5];
  lon0_ = gt[0] + 0.5 * gt[1], lat0_ = gt[3] + 0.5 * gt[5];
  wraps_ = dlon_ * width_ >= 360.0 - 1e-9;
  // The window: the whole grid, or the nodes around the box with two of margin. A box that needs
  // the grid's columns across its seam takes every column (simple, and rare: a raster across the
  // grid's own edge).
  col0_ = 0, row0_ = 0, windowWidth_ = width_, windowHeight_ = height_;
  if (box && std::isfinite((*box)[0]) && std::isfinite((*box)[1]) && std::isfinite((*box)[2]) &&
      std::isfinite((*box)[3])) {
    const double xa = ((*box)[0] - lon0_) / dlon_, xb = ((*box)[2] - lon0_) / dlon_;
    const double ya = ((*box)[1] - lat0_) / dlat_, yb = ((*box)[3] - lat0_) / dlat_;
    long long c0 = static_cast<long long>(std::floor(std::min(xa, xb))) - 2;
    long long c1 = static_cast<long long>(std::ceil(std::max(xa, xb))) + 2;
    const long long r0 = std::max<long long>(0, static_cast<long long>(std::floor(std::min(ya, yb))) - 2);
    const long long r1 = std::min<long long>(height_ - 1, static_cast<long long>(std::ceil(std::max(ya, yb))) + 2);
    if (wraps_ && (c0 < 0 || c1 >= width_)) {
      const auto period = static_cast<long long>(std::llround(360.0 / dlon_));
      const long long shift = period * static_cast<long long>(std::floor(static_cast<double>(c0) / period));
      c0 -= shift, c1 -= shift;  // (the same meridians, from the grid's first turn)
    }
    if (c0 >= 0 && c1 < width_ && c0 <= c1 && r0 <= r1) {
      col0_ = c0, row0_ = r0, windowWidth_ = c1 - c0 + 1, windowHeight_ = r1 - r0 + 1;
    }
  }
  values_.resize(static_cast<std::size_t>(windowWidth_ * windowHeight_));
  GDALRasterBand* band = ds->GetRasterBand(1);
  if (band->RasterIO(GF_Read, static_cast<int>(col0_), static_cast<int>(row0_), static_cast<int>(windowWidth_),
                     static_cast<int>(windowHeight_), values_.data(), static_cast<int>(windowWidth_),
                     static_cast<int>(windowHeight_), GDT_Float32, 0, 0) != CE_None) {
    throw Error(path_ + ": cannot read the geoid grid (" + errors.reason() + ")");
  }
  int hasNodata = 0;
  const double nodata = band->GetNoDataValue(&hasNodata);
  if (hasNodata) {
    for (float& v : values_) {
      if (v == static_cast<float>(nodata)) v = NAN;
    }
  }
}

double Geoid::node(long long col, long long row) const {
  if (wraps_) {
    const auto period = static_cast<long long>(std::llround(360.0 / dlon_));
    col = ((col % period) + period) % period;
    if (col >= width_) col = col - period;  // (a grid with both -180 and 180 columns)
    if (col < 0) return NAN;
  }
  if (col < 0 || col >= width_ || row < 0 || row >= height_) return NAN;
  col -= col0_, row -= row0_;  // (into the window read)
  if (col < 0 || col >= windowWidth_ || row < 0 || row >= windowHeight_) return NAN;
  return values_[static_cast<std::size_t>(row * windowWidth_ + col)];
}

double Geoid::undulation(double lon, double lat) const {
  if (constant_ != 0) return constant_;
  if (ellipsoidal()) return 0;
  double x = (lon - lon0_) / dlon_;
  if (wraps_) x -= 360.0 / dlon_ * std::floor(x * dlon_ / 360.0);
  const double y = std::clamp((lat - lat0_) / dlat_, 0.0, static_cast<double>(height_ - 1));
  const double cf = std::floor(x), rf = std::min(std::floor(y), static_cast<double>(height_ - 2));
  const auto c = static_cast<long long>(cf), r = static_cast<long long>(rf);
  const double fx = x - cf, fy = y - rf;
  const double a = node(c, r), b = node(c + 1, r), d = node(c, r + 1), e = node(c + 1, r + 1);
  return (a * (1 - fx) + b * fx) * (1 - fy) + (d * (1 - fx) + e * fx) * fy;
}

std::pair<double, double> Geoid::rangeOver(double lon0, double lat0, double lon1, double lat1) const {
  if (constant_ != 0) return {constant_, constant_};
  if (ellipsoidal()) return {0.0, 0.0};
  const double xa = (lon0 - lon0_) / dlon_, xb = (lon1 - lon0_) / dlon_;
  const double ya = (lat0 - lat0_) / dlat_, yb = (lat1 - lat0_) / dlat_;
  const auto c0 = static_cast<long long>(std::floor(std::min(xa, xb))) - 1;
  const auto c1 = static_cast<long long>(std::ceil(std::max(xa, xb))) + 1;
  const auto r0 = std::max<long long>(0, static_cast<long long>(std::floor(std::min(ya, yb))) - 1);
  const auto r1 = std::min<long long>(height_ - 1, static_cast<long long>(std::ceil(std::max(ya, yb))) + 1);
  double lo = INFINITY, hi = -INFINITY;
  const long long most = wraps_ ? static_cast<long long>(std::llround(360.0 / dlon_)) + 2 : width_ + 2;
  for (long long r = r0; r <= r1; ++r) {
    for (long long c = c0; c <= std::min(c1, c0 + most); ++c) {
      const double v = node(c, r);
      if (std::isnan(v)) continue;
      lo = std::min(lo, v), hi = std::max(hi, v);
    }
  }
  if (!(lo <= hi))
    throw Error(path_ + ": the geoid grid does not cover longitudes " + std::to_string(lon0) + " to " +
                std::to_string(lon1) + ", latitudes " + std::to_string(lat0) + " to " + std::to_string(lat1));
  return {lo, hi};
}

}  // namespace qota
