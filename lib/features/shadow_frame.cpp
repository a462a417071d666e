// The frame shadows are computed in: a DEM's pixel centres (and its closure's vertices) in
// metres, east-north-up at its centre, on its body's ellipsoid (see qota/shadow.hpp).
#include <Eigen/Geometry>
#include <GeographicLib/Geocentric.hpp>
#include <ogr_spatialref.h>
#include <proj.h>

#include <algorithm>
#include <cmath>
#include <tuple>
#include <atomic>
#include <exception>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>
#include <sstream>

#include "gdal_errors.hpp"
#include "qota/enu.hpp"
#include "qota/error.hpp"
#include "qota/globe.hpp"
#include "qota/shadow.hpp"

namespace qota {
namespace {

constexpr double kDeg = M_PI / 180.0;
// gdaldem's convention for -s on a geographic raster: metres per degree.
constexpr double kMetresPerDegree = 111120.0;

// A raster's axes are x = easting or longitude, y = northing or latitude (GDAL's convention for
// rasters), whatever the CRS's official axis order.
OGRSpatialReference rasterCrs(const DemTerrain& dem) {
  OGRSpatialReference srs;
  if (srs.importFromWkt(dem.crsWkt.c_str()) != OGRERR_NONE) {
    throw Error(dem.path + ": its coordinate reference system cannot be read");
  }
  srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  return srs;
}

// Metres per unit of the DEM's heights: its vertical unit, or -s for a raster without one, times
// -z.
double heightMetres(const DemTerrain& dem, const FrameOptions& o, const OGRSpatialReference* srs) {
  if (!(o.zFactor > 0) || !std::isfinite(o.zFactor)) {
    throw Error("-z/--z-factor must be a positive number, got " + std::to_string(o.zFactor));
  }
  if (!(o.scale >= 0) || !std::isfinite(o.scale)) {
    throw Error("-s/--scale must be a positive number, got " + std::to_string(o.scale));
  }
  double metres = dem.verticalUnit.metresPerUnit;
  if (o.scale > 0) {
    if (dem.verticalUnit.known()) {
      throw Error(dem.path + ": its heights are in '" + dem.verticalUnit.name +
                  "', so -s/--scale (for rasters whose vertical unit is not known) does not apply; "
                  "use -z/--z-factor to scale them");
    }
    double horizontal = 1;  // metres per horizontal unit
    if (srs && srs->IsGeographic()) {
      horizontal = kMetresPerDegree;
    } else if (srs) {
      horizontal = srs->GetLinearUnits();
    }
    metres = horizontal / o.scale;
  }
  return metres * o.zFactor;
}

}  // namespace

std::string celestialBody(const std::string& crsWkt) {
  if (crsWkt.empty()) return "";
  std::string name;
  PJ_CONTEXT* ctx = proj_context_create();
  proj_log_level(ctx, PJ_LOG_NONE);
  if (PJ* crs = proj_create(ctx, crsWkt.c_str())) {
    if (PJ* ellipsoid = proj_get_ellipsoid(ctx, crs)) {
      if (const char* body = proj_get_celestial_body_name(ctx, ellipsoid)) name = body;
      proj_destroy(ellipsoid);
    }
    proj_destroy(crs);
  }
  proj_context_destroy(ctx);
  if (!name.empty() && name != "Non-Earth body") return name;
  // PROJ could not name it: by the size of its ellipsoid.
  OGRSpatialReference srs;
  OGRErr e = OGRERR_NONE;
  if (srs.importFromWkt(crsWkt.c_str()) != OGRERR_NONE) return "unknown";
  const double a = srs.GetSemiMajor(&e);
  if (e != OGRERR_NONE) return "unknown";
  if (a > 6.30e6 && a < 6.45e6) return "Earth";
  if (a > 3.38e6 && a < 3.41e6) return "Mars";
  if (a > 1.73e6 && a < 1.745e6) return "Moon";
  return "a body of radius " + std::to_string(static_cast<long long>(a)) + " m";
}

Eigen::Vector3d LocalFrame::upAt(const Eigen::Vector3d& p) const {
  if (!body.ellipsoid) return Eigen::Vector3d(0, 0, 1);
  const Eigen::Vector3d x = body.rotation.transpose() * p + body.origin;
  const Eigen::Vector3d g(x.x() / (body.a * body.a), x.y() / (body.a * body.a), x.z() / (body.b * body.b));
  return (body.rotation * g).normalized();
}

BodyRays::BodyRays(const LocalFrame& frame, const Eigen::Vector3d& light) : frame_(&frame), light_(light) {
  const LocalFrame::Body& b = frame.body;
  if (!b.ellipsoid) return;
  // The ellipsoid lowered to body.lowest, in coordinates x' = S x that make it the unit sphere.
  // Along the ray x + t d, |S (x + t d)|^2 = qa t^2 + 2 qb t + qc + 1, where qb = (S x).(S d) is
  // linear in the frame point p (x = R^T p + origin): p.k + k0.
  scale_ = Eigen::Vector3d(1 / (b.a + b.lowest), 1 / (b.a + b.lowest), 1 / (b.b + b.lowest));
  const Eigen::Vector3d d = b.rotation.transpose() * light;
  const Eigen::Vector3d s2d = scale_.cwiseProduct(scale_).cwiseProduct(d);
  k_ = b.rotation * s2d;
  k0_ = b.origin.dot(s2d);
  qa_ = scale_.cwiseProduct(d).squaredNorm();
}

bool BodyRays::entersBody(const Eigen::Vector3d& p) const {
  const LocalFrame::Body& b = frame_->body;
  if (!b.ellipsoid) return light_.z() <= 0;
  const double qb = p.dot(k_) + k0_;
  if (qb >= 0) return false;  // the ray climbs away from the ellipsoid
  const Eigen::Vector3d xs = scale_.cwiseProduct(b.rotation.transpose() * p + b.origin);
  const double qc = xs.squaredNorm() - 1;
  return qc <= 0 || qb * qb >= qa_ * qc;  // already below it, or ahead of p it meets it
}

bool LocalFrame::rayEntersBody(const Eigen::Vector3d& p, const Eigen::Vector3d& light) const {
  return BodyRays(*this, light).entersBody(p);
}

double LocalFrame::horizonSlack() const {
  if (!body.ellipsoid) return 0;
  // The largest angle between the centre's up (the frame's z) and a pixel's.
  double cosTilt = 1;
  const Eigen::RowVector3d upRow = body.rotation.row(2);
  for (std::size_t i = 0; i < pixelCount(); ++i) {
    const Eigen::Vector3d x = body.rotation.transpose() * mesh.vertices[i] + body.origin;
    const Eigen::Vector3d g(x.x() / (body.a * body.a), x.y() / (body.a * body.a), x.z() / (body.b * body.b));
    cosTilt = std::min(cosTilt, upRow.dot(g) / g.norm());
  }
  const double tilt = std::acos(std::clamp(cosTilt, -1.0, 1.0));
  const double dip = std::acos(std::clamp((body.b + body.lowest) / (body.b + maxHeight), -1.0, 1.0));
  return (tilt + dip) / kDeg + 0.01;
}

Eigen::Vector3d LocalFrame::towardSun(const SunPosition& sun) const {
  SunPosition inFrame = sun;
  inFrame.azimuth = sun.azimuth + trueNorthFromY;
  return towardSunEnu(inFrame);
}

// Onion peeling (shadow_frame.hpp).
void fillVoids(std::vector<double>& z, int w, int h, std::vector<std::uint32_t>* levels) {
  if (levels) levels->assign(z.size(), 0);
  // The mean of a void pixel's known neighbours (the 8 round it, in one order: the same sum
  // whatever the pass), and whether it has any.
  const auto meanOfKnown = [&](std::size_t i, double& mean) {
    const int c = static_cast<int>(i % w), r = static_cast<int>(i / w);
    double sum = 0;
    int count = 0;
    for (int dr = -1; dr <= 1; ++dr) {
      for (int dc = -1; dc <= 1; ++dc) {
        const int cc = c + dc, rr = r + dr;
        if ((dr || dc) && cc >= 0 && rr >= 0 && cc < w && rr < h) {
          const double v = z[static_cast<std::size_t>(rr) * w + cc];
          if (std::isfinite(v)) sum += v, ++count;
        }
      }
    }
    if (count) mean = sum / count;
    return count > 0;
  };
  // Pass 1 fills the voids next to known pixels; pass p + 1 only voids next to those pass p
  // filled (a void with a known neighbour before pass p + 1 but none before pass p has one that
  // pass p filled). So each pass looks at its rim alone, not at every void left: a void hundreds
  // of pixels wide took hundreds of passes over all of it.
  std::vector<std::size_t> rim;
  for (std::size_t i = 0; i < z.size(); ++i) {
    double mean;
    if (!std::isfinite(z[i]) && meanOfKnown(i, mean)) rim.push_back(i);
  }
  std::vector<std::uint8_t> queued(z.size(), 0);  // in the next pass's rim already
  std::vector<std::pair<std::size_t, double>> fills;
  std::vector<std::size_t> next;
  std::uint32_t pass = 0;
  while (!rim.empty()) {
    ++pass;
    // Every fill of a pass from the heights before it (so their order does not matter; sorted,
    // the neighbours are read in memory order).
    std::sort(rim.begin(), rim.end());
    fills.clear();
    for (std::size_t i : rim) {
      double mean = 0;
      meanOfKnown(i, mean);
      fills.emplace_back(i, mean);
    }
    for (const auto& [i, v] : fills) {
      z[i] = v;
      if (levels) (*levels)[i] = pass;
    }
    next.clear();
    for (const auto& [i, v] : fills) {
      const int c = static_cast<int>(i % w), r = static_cast<int>(i / w);
      for (int dr = -1; dr <= 1; ++dr) {
        for (int dc = -1; dc <= 1; ++dc) {
          const int cc = c + dc, rr = r + dr;
          if (cc < 0 || rr < 0 || cc >= w || rr >= h) continue;
          const std::size_t k = static_cast<std::size_t>(rr) * w + cc;
          if (!std::isfinite(z[k]) && !queued[k]) queued[k] = 1, next.push_back(k);
        }
      }
    }
    rim.swap(next);
  }
  // Voids with nothing known anywhere around them: flat at 0.
  for (std::size_t i = 0; i < z.size(); ++i) {
    if (std::isfinite(z[i])) continue;
    z[i] = 0;
    if (levels) (*levels)[i] = kNeverFilled;
  }
}

LocalFrame localFrame(const DemTerrain& dem, bool flat, double pixelSize) {
  FrameOptions o;
  o.flat = flat;
  o.pixelSize = pixelSize;
  return localFrame(dem, o);
}

namespace {

OGRSpatialReference basisCrs(const FrameBasis& b) { return rasterCrs(b.raster); }

// A projected raster placed on its ellipsoid must lie inside its projection's domain. Outside it
// PROJ may still answer, but not invertibly: a geotransform with rows 10^77 m apart in Web
// Mercator puts every row but the first at the pole, a stack of degenerate triangles that costs
// the shadow search minutes and means nothing. The corners, the edge midpoints and the centre
// must come back from longitude/latitude where they were (to a ten-millionth of their size, or a
// hundredth of a pixel).
void checkInsideProjection(const DemTerrain& dem, OGRCoordinateTransformation& toGeo,
                           OGRCoordinateTransformation& toGrid) {
  const auto& gt = dem.geotransform;
  const double pixel = std::min(std::hypot(gt[1], gt[4]), std::hypot(gt[2], gt[5]));
  for (const double r : {0.0, (dem.height - 1) / 2.0, dem.height - 1.0}) {
    for (const double c : {0.0, (dem.width - 1) / 2.0, dem.width - 1.0}) {
      const auto xy = dem.pixelCentre(c, r);
      double x = xy[0], y = xy[1];
      const bool back = toGeo.Transform(1, &x, &y) && toGrid.Transform(1, &x, &y);
      const double tolerance = 1e-7 * std::max({std::fabs(xy[0]), std::fabs(xy[1]), 1.0}) + 0.01 * pixel;
      if (!back || !(std::fabs(x - xy[0]) <= tolerance && std::fabs(y - xy[1]) <= tolerance)) {
        std::ostringstream what;
        what << dem.path << ": pixel (" << c << ", " << r << ") at (" << xy[0] << ", " << xy[1]
             << ") is outside the domain of the raster's projection ("
             << (back ? "it comes back from longitude/latitude elsewhere" : "it has no longitude/latitude")
             << "); check its geotransform, or shadow it with --flat";
        throw Error(what.str());
      }
    }
  }
}

// The heights' reference on the ellipsoid and the range of its undulation over the raster: over
// the longitudes and latitudes of the raster's edges (sampled along them: a projected raster's
// are curves) and its inside, which lies between them.
void geoidOver(FrameBasis& b, OGRCoordinateTransformation* toGeo) {
  b.heightRef = heightReferenceOf(b.raster, b.options.heightRef);
  if (b.heightRef.ellipsoidal()) {
    b.geoid = std::make_shared<const Geoid>();
    return;
  }
  const DemTerrain& dem = b.raster;
  constexpr int kSamples = 64;
  double lon0 = INFINITY, lon1 = -INFINITY, lat0 = INFINITY, lat1 = -INFINITY;
  const auto& gt = dem.geotransform;
  for (int k = 0; k <= kSamples; ++k) {
    const double t = static_cast<double>(k) / kSamples;
    for (const auto& [c, r] : {std::pair{t * dem.width, 0.0}, std::pair{t * dem.width, double(dem.height)},
                               std::pair{0.0, t * dem.height}, std::pair{double(dem.width), t * dem.height}}) {
      double x = gt[0] + c * gt[1] + r * gt[2], y = gt[3] + c * gt[4] + r * gt[5];
      if (toGeo && !toGeo->Transform(1, &x, &y)) continue;
      lon0 = std::min(lon0, x), lon1 = std::max(lon1, x), lat0 = std::min(lat0, y), lat1 = std::max(lat1, y);
    }
  }
  if (!(lon0 <= lon1 && lat0 <= lat1)) throw Error(dem.path + ": its edges cannot be converted to longitude/latitude");
  // Only the grid's nodes over the raster (two of margin beyond the box of its sampled edges):
  // kilobytes where EGM96's whole grid is 4 MiB, which counts in a small --max-memory.
  b.geoid = std::make_shared<const Geoid>(b.heightRef, std::array<double, 4>{lon0, lat0, lon1, lat1});
  std::tie(b.geoidLow, b.geoidHigh) = b.geoid->rangeOver(lon0, std::max(lat0, -90.0), lon1, std::min(lat1, 90.0));
}

// The raster's description without its mesh: copying millions of vertices to drop them took a
// tenth of a viewshed's time. (Every field of DemTerrain but mesh.)
DemTerrain describedOnly(const DemTerrain& dem) {
  DemTerrain d;
  d.path = dem.path, d.driver = dem.driver, d.width = dem.width, d.height = dem.height;
  d.geotransform = dem.geotransform, d.crsWkt = dem.crsWkt, d.nodata = dem.nodata;
  d.nodataPixels = dem.nodataPixels, d.filledPixels = dem.filledPixels, d.band = dem.band;
  d.integerValues = dem.integerValues, d.estimatedBytes = dem.estimatedBytes;
  d.verticalUnit = dem.verticalUnit, d.verticalReference = dem.verticalReference, d.lonLat = dem.lonLat;
  d.mapping = dem.mapping;
  return d;
}

}  // namespace

FrameBasis frameBasis(const DemTerrain& dem, const FrameOptions& o) {
  FrameBasis b;
  b.raster = describedOnly(dem);
  b.options = o;
  LocalFrame& f = b.shared;
  f.width = dem.width;
  f.height = dem.height;
  const int w = dem.width, h = dem.height;
  if (w < 1 || h < 1)
    throw Error(dem.path + ": a raster of " + std::to_string(w) + " x " + std::to_string(h) + " pixels");
  std::optional<OGRSpatialReference> srs;
  if (!dem.crsWkt.empty()) srs = rasterCrs(dem);
  f.metresPerUnit = heightMetres(dem, o, srs ? &*srs : nullptr);
  const auto& gt = dem.geotransform;
  const double cc = (w - 1) / 2.0, cr = (h - 1) / 2.0;
  const auto centre = dem.pixelCentre(cc, cr);
  b.geographic = srs && srs->IsGeographic();
  const bool ellipsoid = srs && !o.flat;
  f.body.name = srs ? celestialBody(dem.crsWkt) : "";

  // The closure: the outer half pixel always; round the globe and over the poles on an ellipsoid.
  b.closure.border = true;
  if (ellipsoid && b.geographic && gt[2] == 0 && gt[4] == 0 && gt[1] > 0 && gt[5] < 0) {
    b.closure.wrapsColumns = std::fabs(w * gt[1] - 360.0) < 0.5 * gt[1];
    const double top = dem.pixelCentre(0, 0)[1], bottom = dem.pixelCentre(0, h - 1)[1];
    b.closure.northCap = b.closure.wrapsColumns && 90.0 - top <= -gt[5] && top < 90.0;
    b.closure.southCap = b.closure.wrapsColumns && bottom + 90.0 <= -gt[5] && bottom > -90.0;
  }
  if (!srs) {
    if (!(o.pixelSize > 0) || !std::isfinite(o.pixelSize)) {
      throw Error(dem.path +
                  ": the raster has no coordinate reference system, so the size of its "
                  "pixels in metres is unknown; give it with --pixel-size METRES");
    }
    f.description = "pixel grid, " + std::to_string(o.pixelSize) + " m per pixel (no CRS)";
    return b;
  }
  demEllipsoid(dem, b.a, b.flattening);
  double lon0 = centre[0], lat0 = centre[1];
  if (!b.geographic) {
    detail::QuietGdalErrors quiet;  // PROJ's own complaints: the errors below say what failed
    OGRSpatialReference geo;
    geo.CopyGeogCSFrom(&*srs);
    geo.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
    std::unique_ptr<OGRCoordinateTransformation> toGeo(OGRCreateCoordinateTransformation(&*srs, &geo));
    std::unique_ptr<OGRCoordinateTransformation> toGrid(OGRCreateCoordinateTransformation(&geo, &*srs));
    if (!toGeo || !toGrid) throw Error(dem.path + ": its CRS cannot be converted to longitude/latitude");
    if (!toGeo->Transform(1, &lon0, &lat0))
      throw Error(dem.path + ": its centre cannot be converted to longitude/latitude");
    if (ellipsoid) checkInsideProjection(dem, *toGeo, *toGrid);
    if (ellipsoid) geoidOver(b, toGeo.get());
    // Where true north points on the grid at the centre (for a flat projected frame).
    double nx = lon0, ny = lat0 + 0.01;
    if (toGrid->Transform(1, &nx, &ny)) f.trueNorthFromY = std::atan2(nx - centre[0], ny - centre[1]) / kDeg;
  }
  if (ellipsoid && b.geographic) geoidOver(b, nullptr);
  f.geographicLocation = true;
  f.centreLon = lon0;
  f.centreLat = lat0;
  if (ellipsoid) {
    // The frame is the enu mapping's at the centre, on the ellipsoid (height 0).
    const EnuMapping enu(lat0, lon0, 0.0, b.a, b.flattening);
    f.body.ellipsoid = true;
    f.body.a = b.a;
    f.body.b = b.a * (1 - b.flattening);
    f.body.rotation = enu.frame().rotation;
    f.body.origin = enu.origin();
    f.trueNorthFromY = 0;
    f.description = std::string(b.geographic ? "" : "projected grid put ") + "on the " +
                    (f.body.name.empty() ? "" : f.body.name + " ") + "ellipsoid (a = " + std::to_string(b.a) +
                    " m), east-north-up at the centre" + (b.closure.wrapsColumns ? ", closed round the globe" : "") +
                    (b.closure.northCap || b.closure.southCap ? " and over the poles" : "") + "; heights over the " +
                    b.heightRef.describe();
  } else {
    f.description =
        b.geographic ? "flat east-north-up metres around the centre (--flat)" : "projected grid metres (--flat)";
  }
  return b;
}

void heightsInMetres(const FrameBasis& b, const PixelWindow& window, std::vector<double>& z,
                     std::vector<std::uint8_t>& valid) {
  const std::size_t n = static_cast<std::size_t>(window.width) * window.height;
  if (z.size() != n) throw Error(b.raster.path + ": a window of heights of the wrong size");
  valid.resize(n);
  const double metres = b.shared.metresPerUnit;
  for (std::size_t i = 0; i < n; ++i) {
    z[i] *= metres;
    valid[i] = std::isfinite(z[i]);
    if (valid[i] && !(std::fabs(z[i]) <= kMaxHeight)) {
      throw Error(b.raster.path + ": the height at pixel (" + std::to_string(window.col + i % window.width) + ", " +
                  std::to_string(window.row + i / window.width) + ") is " + std::to_string(z[i]) +
                  " m, beyond any terrain (1e9 m); is it nodata, or the wrong unit?");
    }
  }
}

namespace {

// Points of a frame on an ellipsoid, placed block after block by one placer (a thread's: the
// CRS's conversion to longitude and latitude is a PROJ object, for one thread at a time).
class EllipsoidPlacer {
 public:
  explicit EllipsoidPlacer(const FrameBasis& b) : b_(b), earth_(b.a, b.flattening) {
    if (b.geographic) return;
    const OGRSpatialReference srs = basisCrs(b);
    OGRSpatialReference geo;
    geo.CopyGeogCSFrom(&srs);
    geo.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
    toGeo_.reset(OGRCreateCoordinateTransformation(&srs, &geo));
    if (!toGeo_) throw Error(b.raster.path + ": its CRS cannot be converted to longitude/latitude");
  }

  // The frame points of pixel positions (col, row) `height` metres over the frame's reference
  // (pole: framePoints'), onto out.
  void place(std::span<const double> col, std::span<const double> row, std::span<const double> height,
             std::span<const int> pole, Eigen::Vector3d* out) {
    const DemTerrain& dem = b_.raster;
    const LocalFrame& f = b_.shared;
    const std::size_t vertexCount = col.size();
    const auto& gt = dem.geotransform;
    // Longitude and latitude of every vertex, on the CRS's own ellipsoid.
    lon_.resize(vertexCount), lat_.resize(vertexCount);
    for (std::size_t i = 0; i < vertexCount; ++i) {
      lon_[i] = gt[0] + col[i] * gt[1] + row[i] * gt[2];
      lat_[i] = gt[3] + col[i] * gt[4] + row[i] * gt[5];
    }
    if (toGeo_) {
      ok_.assign(vertexCount, 0);
      toGeo_->Transform(vertexCount, lon_.data(), lat_.data(), nullptr, ok_.data());
      for (std::size_t i = 0; i < vertexCount; ++i) {
        if (!ok_[i] || !std::isfinite(lon_[i]) || !std::isfinite(lat_[i])) {
          throw Error(dem.path + ": pixel (" + std::to_string(col[i]) + ", " + std::to_string(row[i]) +
                      ") cannot be converted to longitude/latitude; shadow it with --flat");
        }
      }
    }
    for (std::size_t i = 0; i < vertexCount; ++i) {
      double lon = lon_[i], lat = lat_[i];
      if (!pole.empty() && pole[i]) lon = 0, lat = 90.0 * pole[i];
      if (!(std::fabs(lat) <= 90.0)) {
        throw Error(dem.path + ": pixel (" + std::to_string(col[i]) + ", " + std::to_string(row[i]) +
                    ") is at latitude " + std::to_string(lat) + ", beyond the pole");
      }
      // Over the ellipsoid: the height over the geoid plus the geoid's undulation there.
      const double n = b_.geoid ? b_.geoid->undulation(lon, lat) : 0.0;
      if (std::isnan(n)) {
        throw Error(dem.path + ": pixel (" + std::to_string(col[i]) + ", " + std::to_string(row[i]) + ") at " +
                    std::to_string(lon) + ", " + std::to_string(lat) + " is outside the geoid grid " +
                    b_.heightRef.grid);
      }
      Eigen::Vector3d X;
      earth_.Forward(lat, lon, height[i] + n, X.x(), X.y(), X.z());
      out[i] = f.body.rotation * (X - f.body.origin);
    }
  }

 private:
  const FrameBasis& b_;
  const GeographicLib::Geocentric earth_;
  std::unique_ptr<OGRCoordinateTransformation> toGeo_;  // (none: a geographic raster)
  std::vector<double> lon_, lat_;
  std::vector<int> ok_;
};

// Flat frames' points: one expression a point (a geographic raster's poles at their longitude
// and latitude; other rasters have none).
void placeFlat(const FrameBasis& b, std::span<const double> col, std::span<const double> row,
               std::span<const double> height, std::span<const int> pole, Eigen::Vector3d* out) {
  const FlatPlacement flat(b);
  for (std::size_t i = 0; i < col.size(); ++i) {
    const int p = pole.empty() ? 0 : pole[i];
    out[i] = p && flat.lonLat() ? flat.atLonLat(0, 90.0 * p, height[i]) : flat.at(col[i], row[i], height[i]);
  }
}

}  // namespace

std::vector<Eigen::Vector3d> framePoints(const FrameBasis& b, std::span<const double> col, std::span<const double> row,
                                         std::span<const double> height, std::span<const int> pole) {
  const std::size_t vertexCount = col.size();
  if (row.size() != vertexCount || height.size() != vertexCount || (!pole.empty() && pole.size() != vertexCount)) {
    throw Error("frame points: as many columns, rows, heights (and poles) are needed");
  }
  std::vector<Eigen::Vector3d> out(vertexCount);
  if (b.shared.body.ellipsoid) {
    EllipsoidPlacer(b).place(col, row, height, pole, out.data());
  } else {
    placeFlat(b, col, row, height, pole, out.data());
  }
  return out;
}

FlatPlacement::FlatPlacement(const FrameBasis& b) {
  const DemTerrain& dem = b.raster;
  const LocalFrame& f = b.shared;
  if (f.body.ellipsoid) throw Error(dem.path + ": a frame on an ellipsoid is not placed flat");
  std::copy(dem.geotransform.begin(), dem.geotransform.end(), gt_);
  cc_ = (dem.width - 1) / 2.0, cr_ = (dem.height - 1) / 2.0;
  if (dem.crsWkt.empty()) {
    // Pixel grid, rows running south.
    kind_ = Kind::Pixels;
    pixel_ = b.options.pixelSize;
  } else if (b.geographic) {
    // Longitude and latitude scaled linearly by the ellipsoid's radii of curvature at the
    // centre: no curvature.
    kind_ = Kind::LonLat;
    lon0_ = f.centreLon, lat0_ = f.centreLat;
    const double fl = b.flattening, e2 = fl * (2 - fl), s = std::sin(lat0_ * kDeg);
    const double wq = std::sqrt(1 - e2 * s * s);
    nRad_ = b.a / wq, mRad_ = b.a * (1 - e2) / (wq * wq * wq);
    cosLat0_ = std::cos(lat0_ * kDeg);
  } else {
    kind_ = Kind::Projected;
    const auto centre = dem.pixelCentre(cc_, cr_);
    centreX_ = centre[0], centreY_ = centre[1];
    unit_ = basisCrs(b).GetLinearUnits();
  }
}

Eigen::Vector3d FlatPlacement::atLonLat(double lon, double lat, double height) const {
  return {(lon - lon0_) * kDeg * nRad_ * cosLat0_, (lat - lat0_) * kDeg * mRad_, height};
}

Eigen::Vector3d FlatPlacement::at(double col, double row, double height) const {
  if (kind_ == Kind::Pixels) return {(col - 0.5 - cc_) * pixel_, -(row - 0.5 - cr_) * pixel_, height};
  // The raster's position (its CRS's units or degrees).
  const double x = gt_[0] + col * gt_[1] + row * gt_[2];
  const double y = gt_[3] + col * gt_[4] + row * gt_[5];
  if (kind_ == Kind::LonLat) return atLonLat(x, y, height);
  return {(x - centreX_) * unit_, (y - centreY_) * unit_, height};
}

LocalFrame windowFrame(const FrameBasis& b, const PixelWindow& window, std::vector<double> z,
                       std::vector<std::uint8_t> valid, bool triangles) {
  LocalFrame f = windowFrame(b, window, std::span<const double>(z), std::move(valid), false);
  if (triangles) f.mesh.indices = f.grid.indices();
  return f;
}

LocalFrame windowFrame(const FrameBasis& b, const PixelWindow& window, std::span<const double> z,
                       std::vector<std::uint8_t> valid, bool triangles, unsigned threads) {
  LocalFrame f = gridFrame(b, window, std::move(valid));
  placeVertices(f, b, z, threads);
  if (triangles) f.mesh.indices = f.grid.indices();
  return f;
}

LocalFrame gridFrame(const FrameBasis& b, const PixelWindow& window, std::vector<std::uint8_t> valid) {
  const DemTerrain& dem = b.raster;
  const int w = window.width, h = window.height;
  const std::size_t n = static_cast<std::size_t>(std::max(w, 0)) * std::max(h, 0);
  if (w < 1 || h < 1 || window.col < 0 || window.row < 0 || window.col + w > dem.width || window.row + h > dem.height ||
      valid.size() != n) {
    throw Error(dem.path + ": window (" + std::to_string(window.col) + ", " + std::to_string(window.row) + ") of " +
                std::to_string(w) + " x " + std::to_string(h) + " pixels is not on the raster or not its heights");
  }
  LocalFrame f = b.shared;
  f.width = w;
  f.height = h;
  f.window = window;
  f.valid = std::move(valid);
  const bool whole = w == dem.width && h == dem.height;
  const RasterGrid::Closure& closure = b.closure;
  if (!whole && (closure.wrapsColumns || closure.northCap || closure.southCap)) {
    throw Error(dem.path + ": the raster is closed round the globe, so it is shadowed whole, not by windows");
  }
  f.grid = RasterGrid(w, h, closure);
  f.gridMesh = true;
  return f;
}

void placeVertices(LocalFrame& f, const FrameBasis& b, std::span<const double> z, unsigned threadsAsked) {
  const int w = f.width, h = f.height;
  const PixelWindow& window = f.window;
  const std::size_t n = f.pixelCount();
  if (z.size() != n) {
    throw Error(b.raster.path + ": " + std::to_string(z.size()) + " heights for a window of " + std::to_string(n) +
                " pixels");
  }
  // Every vertex: where it stands in the raster's pixel coordinates, and its height in metres,
  // placed a block at a time (the positions of a whole raster at once would need as much memory
  // again as its points), the blocks shared by the threads in turn. (On an ellipsoid a point
  // costs some 300 ns, most of it the CRS's conversion to longitude and latitude: 1.2 s for a
  // 2000 x 2000 raster on one thread.)
  const std::size_t vertexCount = f.grid.vertexCount();
  constexpr std::size_t kBlock = std::size_t{1} << 16;
  const std::size_t blocks = (vertexCount + kBlock - 1) / kBlock;
  f.mesh.vertices.resize(vertexCount);
  std::atomic<std::size_t> next{0};
  std::atomic<bool> stop{false};
  std::mutex failing;
  std::size_t failedBlock = blocks;
  std::exception_ptr failure;  // the first failing block's (the same whatever the threads)
  const auto work = [&] {
    std::size_t k = 0;
    try {
      std::optional<EllipsoidPlacer> placer;  // (the thread's own)
      if (b.shared.body.ellipsoid) placer.emplace(b);
      std::vector<double> col, row, height;
      std::vector<int> pole;
      while (!stop && (k = next++) < blocks) {
        const std::size_t first = k * kBlock, count = std::min(kBlock, vertexCount - first);
        col.resize(count), row.resize(count), height.resize(count), pole.assign(count, 0);
        for (std::size_t j = 0; j < count; ++j) {
          const std::size_t i = first + j;
          if (i < n) {
            col[j] = static_cast<double>(window.col + static_cast<int>(i % w)) + 0.5;
            row[j] = static_cast<double>(window.row + static_cast<int>(i / w)) + 0.5;
            height[j] = z[i];
            continue;
          }
          const RasterGrid::ExtraVertex& e = f.grid.extraVertices()[i - n];
          col[j] = e.col + window.col, row[j] = e.row + window.row, pole[j] = e.pole;
          if (e.pole == 0) {
            height[j] = z[e.pixel];
            continue;
          }
          const std::size_t r = e.pole > 0 ? 0 : static_cast<std::size_t>(h - 1);  // the pole's row
          double sum = 0;
          for (std::size_t c = 0; c < static_cast<std::size_t>(w); ++c) sum += z[r * w + c];
          height[j] = sum / w;
        }
        Eigen::Vector3d* out = f.mesh.vertices.data() + first;
        placer ? placer->place(col, row, height, pole, out) : placeFlat(b, col, row, height, pole, out);
      }
    } catch (...) {
      const std::lock_guard<std::mutex> hold(failing);
      if (k < failedBlock) failedBlock = k, failure = std::current_exception();
      stop = true;
    }
  };
  // (A small frame on one thread: each more thread keeps its own blocks' buffers and heap, a
  // megabyte or two that a small job's memory estimate has no room for.)
  constexpr std::size_t kBlocksPerThread = 4;
  const unsigned most = threadsAsked ? threadsAsked : std::clamp(std::thread::hardware_concurrency(), 1u, 8u);
  const unsigned threads =
      static_cast<unsigned>(std::min<std::size_t>((blocks + kBlocksPerThread - 1) / kBlocksPerThread, most));
  {
    std::vector<std::jthread> pool;
    for (unsigned t = 1; t < threads; ++t) pool.emplace_back(work);
    work();
  }
  if (failure) {
    f.mesh.vertices.clear();
    std::rethrow_exception(failure);
  }
}

void completeBasis(FrameBasis& b, double minHeight, double maxHeight, const LocalFrame& centre) {
  LocalFrame& f = b.shared;
  f.minHeight = minHeight, f.maxHeight = maxHeight;
  if (!(f.minHeight <= f.maxHeight)) f.minHeight = f.maxHeight = 0;
  // Over the ellipsoid: the heights over the geoid plus its undulation, which lies in this range.
  f.minHeight += b.geoidLow, f.maxHeight += b.geoidHigh;
  const int w = b.raster.width, h = b.raster.height;
  // The centre square's top-left pixel, in the centre frame's own numbering.
  const int cc = (w - 1) / 2 - centre.window.col, cr = (h - 1) / 2 - centre.window.row;
  if (w > 1 && h > 1) {
    if (cc < 0 || cr < 0 || cc + 1 >= centre.width || cr + 1 >= centre.height) {
      throw Error(b.raster.path + ": the window given for the frame's centre does not hold it");
    }
    // Every vertex has a position (voids are filled), so the centre's neighbours give the size.
    const std::size_t ci = static_cast<std::size_t>(cr) * centre.width + static_cast<std::size_t>(cc);
    const auto& v = centre.mesh.vertices;
    f.pixelSizeX = (v[ci + 1] - v[ci]).head<2>().norm();
    f.pixelSizeY = (v[ci + centre.width] - v[ci]).head<2>().norm();
  }
  // Below this height a ray is inside the body: the lowest terrain, less a margin for the chords
  // between pixel centres (a triangle sags below its corners by less than d^2 / 2R on a sphere,
  // d its longest side) and a centimetre for rounding.
  const double diagonal = std::hypot(f.pixelSizeX, f.pixelSizeY);
  f.body.lowest = f.minHeight - 0.01 - (f.body.ellipsoid ? diagonal * diagonal / (2 * f.body.b) : 0.0);
  // Which way the grid's triangles turn seen from above: the same for all of them (the rows and
  // columns keep their orientation on the ellipsoid), so the centre's first one tells.
  if (w > 1 && h > 1) {
    const std::uint32_t tl = static_cast<std::uint32_t>(static_cast<std::size_t>(cr) * centre.width + cc);
    const std::uint32_t bl = tl + static_cast<std::uint32_t>(centre.width), br = bl + 1;
    const auto& v = centre.mesh.vertices;
    const Eigen::Vector3d normal = (v[bl] - v[tl]).cross(v[br] - v[tl]);
    f.gridWinding = normal.dot(centre.upAt(v[tl])) >= 0 ? 1 : -1;
  }
  b.complete = true;
}

void adoptBasis(LocalFrame& frame, const FrameBasis& b) {
  frame.minHeight = b.shared.minHeight, frame.maxHeight = b.shared.maxHeight;
  frame.pixelSizeX = b.shared.pixelSizeX, frame.pixelSizeY = b.shared.pixelSizeY;
  frame.body.lowest = b.shared.body.lowest;
  frame.gridWinding = b.shared.gridWinding;
}

LocalFrame localFrame(const DemTerrain& dem, const FrameOptions& o) {
  FrameBasis basis;
  return localFrame(dem, o, basis);
}

LocalFrame localFrame(const DemTerrain& dem, const FrameOptions& o, FrameBasis& basis, bool triangles) {
  const int w = dem.width, h = dem.height;
  const std::size_t n = static_cast<std::size_t>(std::max(w, 0)) * static_cast<std::size_t>(std::max(h, 0));
  if (w < 1 || h < 1 || (dem.mesh.vertices.size() != n && dem.heights.size() != n)) {
    throw Error(dem.path + ": not a raster grid (" + std::to_string(dem.mesh.vertices.size()) + " vertices for " +
                std::to_string(w) + " x " + std::to_string(h) + " pixels)");
  }
  basis = frameBasis(dem, o);
  const PixelWindow whole{0, 0, w, h};
  // Heights in metres with the voids filled (for occlusion only), and which pixels have data.
  std::vector<double> z(n);
  std::vector<std::uint8_t> valid;
  for (std::size_t i = 0; i < n; ++i) z[i] = dem.heightOf(i);
  heightsInMetres(basis, whole, z, valid);
  double lo = INFINITY, hi = -INFINITY;
  for (std::size_t i = 0; i < n; ++i) {
    if (valid[i]) lo = std::min(lo, z[i]), hi = std::max(hi, z[i]);
  }
  if (o.fillVoids) {
    fillVoids(z, w, h);
  } else {
    for (double& v : z) v = std::isnan(v) ? (lo <= hi ? lo : 0.0) : v;
  }
  LocalFrame f = windowFrame(basis, whole, std::move(z), std::move(valid), triangles);
  completeBasis(basis, lo, hi, f);
  adoptBasis(f, basis);
  return f;
}

}  // namespace qota
