// qota viewshed: what an observer sees of a DEM (see qota_tools.hpp and qota/viewshed.hpp).
#include "qota/viewshed.hpp"

#include <Eigen/Geometry>
#include <ogr_spatialref.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <ostream>

#include "qota/error.hpp"
#include "qota/memory_budget.hpp"
#include "qota_tools.hpp"
#include "raster_output.hpp"
#include "shadow_parts.hpp"
#include "text_output.hpp"

namespace qota::tools {
namespace {

// The observer in the raster's CRS: as given, or transformed from --srs.
std::array<double, 2> observerOnRaster(const ViewshedOptions& o, const DemTerrain& dem) {
  if (o.srs.empty()) return o.observer;
  if (dem.crsWkt.empty()) throw Error(o.source + ": the raster has no CRS, so --srs cannot place the observer on it");
  OGRSpatialReference from, to;
  if (from.SetFromUserInput(o.srs.c_str()) != OGRERR_NONE) {
    throw Error("--srs '" + o.srs + "' is not a coordinate reference system GDAL knows");
  }
  to.importFromWkt(dem.crsWkt.c_str());
  from.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  to.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  const std::unique_ptr<OGRCoordinateTransformation> ct(OGRCreateCoordinateTransformation(&from, &to));
  double x = o.observer[0], y = o.observer[1];
  if (!ct || !ct->Transform(1, &x, &y) || !std::isfinite(x) || !std::isfinite(y)) {
    throw Error("--observer " + formatNumber(o.observer[0]) + "," + formatNumber(o.observer[1]) +
                " cannot be converted from --srs '" + o.srs + "' to the raster's CRS");
  }
  return {x, y};
}

void checkOptions(const ViewshedOptions& o, const std::string& format) {
  if (o.output.empty()) throw Error("an output file is needed: -o OUT");
  const int values[4] = {o.visibleValue, o.hiddenValue, o.nodataValue, o.outOfRangeValue};
  for (int v : values) {
    if (v < 0 || v > 255) throw Error("output values must be 0..255, got " + std::to_string(v));
  }
  for (int a = 0; a < 4; ++a) {
    for (int b = a + 1; b < 4; ++b) {
      if (values[a] == values[b]) {
        throw Error("--visible-value " + std::to_string(o.visibleValue) + ", --invisible-value " +
                    std::to_string(o.hiddenValue) + ", --nodata-value " + std::to_string(o.nodataValue) +
                    " and --out-of-range-value " + std::to_string(o.outOfRangeValue) +
                    " must differ, or the pixels could not be told apart");
      }
    }
  }
  if (format == "VRT" || format == "MEM") {
    throw Error(o.output + ": the " + format +
                " format holds no pixels of its own; write a GeoTIFF (.tif) or another format that stores them");
  }
  for (const std::string* path : {&o.output, &o.png}) {
    if (!path->empty() && sameFile(*path, o.source)) throw Error(*path + " is the input DEM; give another output name");
  }
  if (!o.png.empty() && sameFile(o.png, o.output)) throw Error("--png and -o name the same file");
}

// A grey hillshade (light from the north-west, 45 degrees up) where visible, darkened where
// hidden, darker still beyond the range; nodata black.
std::vector<double> preview(const LocalFrame& f, const std::vector<Sight>& sight) {
  const int w = f.width, h = f.height;
  const Eigen::Vector3d light = Eigen::Vector3d(-0.5, 0.5, std::sqrt(0.5)).normalized();
  std::vector<double> grey(f.pixelCount(), 0.0);
  const auto& v = f.mesh.vertices;
  for (int r = 0; r < h; ++r) {
    for (int c = 0; c < w; ++c) {
      const std::size_t i = static_cast<std::size_t>(r) * w + c;
      if (sight[i] == Sight::NoData) continue;
      const auto at = [&](int cc, int rr) -> const Eigen::Vector3d& {
        return v[static_cast<std::size_t>(std::clamp(rr, 0, h - 1)) * w + std::clamp(cc, 0, w - 1)];
      };
      const Eigen::Vector3d n = (at(c + 1, r) - at(c - 1, r)).cross(at(c, r - 1) - at(c, r + 1));
      const double shade = n.squaredNorm() > 0 ? std::max(0.0, n.normalized().dot(light)) : 0.5;
      const double scale = sight[i] == Sight::Visible ? 1.0 : sight[i] == Sight::Hidden ? 0.35 : 0.15;
      grey[i] = 40 + 215 * (0.3 + 0.7 * shade) * scale;
    }
  }
  return grey;
}

}  // namespace

int viewshed(const ViewshedOptions& given, std::ostream& out, std::ostream& err) {
  try {
    ViewshedOptions o = given;
    o.flat = flatByMapping(o.mapping, o.flat, "viewshed", "draws no line of sight on a DEM's grid");
    for (const std::string* path : {&o.output, &o.png}) {
      if (!path->empty()) OutputStage::checkTarget(*path);
    }
    const std::string format = o.output.empty() ? "" : o.format.empty() ? driverForPath(o.output) : o.format;
    checkOptions(o, format);
    const int mostValue = std::max({o.visibleValue, o.hiddenValue, o.nodataValue, o.outOfRangeValue});
    for (const std::string& warning : checkCreationOptions(format, o.creationOptions, true, mostValue)) {
      err << "qota viewshed: warning: GDAL: " << warning << '\n';
    }
    DemOptions demOptions;
    demOptions.band = o.band;
    demOptions.lonLatAsCartesian = true;  // read as lon/lat: the frame puts it on its ellipsoid
    demOptions.then = memory::kShadow;
    const DemTerrain dem = loadDem(o.source, demOptions);

    qota::ViewshedOptions v;
    const auto [x, y] = observerOnRaster(o, dem);
    v.observerX = x, v.observerY = y;
    v.observerHeight = o.observerHeight, v.targetHeight = o.targetHeight, v.maxDistance = o.maxDistance;
    v.frame = frameOptionsOf(o);
    v.index = o.index;
    if (!o.quiet) out << "qota viewshed: " << o.source << " -> " << o.output << " (" << format << ")\n";
    const Viewshed seen = qota::viewshed(dem, v, termProgress(o.quiet, 0, 1));
    if (!o.quiet) {
      out << "frame: " << seen.frameDescription << '\n'
          << "observer: " << formatNumber(x) << ", " << formatNumber(y) << ", " << formatNumber(o.observerHeight)
          << " m above the surface at " << formatNumber(seen.surface, 3) << " m\n"
          << "visible: " << seen.visible << " of " << seen.tested << " pixels tested ("
          << formatNumber(seen.tested ? 100.0 * seen.visible / seen.tested : 0.0, 2) << " %)\n";
    }
    std::vector<double> values(seen.sight.size());
    for (std::size_t i = 0; i < values.size(); ++i) {
      const Sight s = seen.sight[i];
      values[i] = s == Sight::Visible  ? o.visibleValue
                  : s == Sight::Hidden ? o.hiddenValue
                  : s == Sight::NoData ? o.nodataValue
                                       : o.outOfRangeValue;
    }
    OutputStage stage;
    RasterWrite w{o.output,
                  format,
                  o.creationOptions,
                  true,
                  double(o.nodataValue),
                  true,
                  {{"QOTA_TOOL", "viewshed"},
                   {"QOTA_OBSERVER", formatNumber(x) + "," + formatNumber(y)},
                   {"QOTA_OBSERVER_HEIGHT", formatNumber(o.observerHeight)},
                   {"QOTA_TARGET_HEIGHT", formatNumber(o.targetHeight)},
                   {"QOTA_MAX_DISTANCE", formatNumber(o.maxDistance)},
                   {"QOTA_VALUES", "visible=" + std::to_string(o.visibleValue) + ",invisible=" +
                                       std::to_string(o.hiddenValue) + ",nodata=" + std::to_string(o.nodataValue) +
                                       ",out_of_range=" + std::to_string(o.outOfRangeValue)}}};
    writeRaster(w, dem, values, stage);
    if (!o.png.empty()) {
      const LocalFrame frame = localFrame(dem, v.frame);
      writeRaster({o.png, "PNG", {}, true, 0.0, true}, dem, preview(frame, seen.sight), stage);
    }
    stage.commit();
    if (!o.quiet) out << "written: " << o.output << (o.png.empty() ? "" : " and " + o.png) << '\n';
    return 0;
  } catch (...) {
    return reportFailure("viewshed", err);
  }
}

}  // namespace qota::tools
