// qota shadow: a directional light's shadows on a DEM (see qota_tools.hpp and qota/shadow.hpp).
#include <Eigen/Geometry>
#include <gdal_priv.h>

#include <cmath>
#include <iostream>

#include "qota/error.hpp"
#include "qota/shadow.hpp"
#include "qota_tools.hpp"
#include "raster_output.hpp"
#include "text_output.hpp"

namespace qota::tools {
namespace {

constexpr double kDeg = M_PI / 180.0;

// GDAL's terminal progress ("0...10...20..."), scaled into [lo, hi] of the whole run.
Progress termProgress(bool quiet, double lo, double hi) {
  if (quiet) return {};
  return [lo, hi](double done, const char* message) {
    return GDALTermProgress(lo + (hi - lo) * done, message, nullptr) != FALSE;
  };
}

struct LightChoice {
  Eigen::Vector3d toward;    // unit, frame coordinates
  std::string description;
};

int lightKinds(const ShadowOptions& o) {
  return (o.azimuth || o.altitude ? 1 : 0) + (o.sunVector ? 1 : 0) + (o.time.empty() ? 0 : 1);
}

std::optional<int> utcOffset(const ShadowOptions& o) {
  if (o.tz.empty()) return std::nullopt;
  return parseUtcOffset(o.tz);
}

void requireLocation(const LocalFrame& frame, const std::string& path) {
  if (!frame.geographicLocation) {
    throw Error(path + ": the raster has no coordinate reference system, so its place on Earth (and "
                "the sun's position there) is unknown; give -az/-alt or --sun-vector instead");
  }
}

LightChoice chooseLight(const ShadowOptions& o, const LocalFrame& frame) {
  if (o.sunVector) {
    if (!o.sunVector->allFinite() || o.sunVector->squaredNorm() == 0) {
      throw Error("--sun-vector must be a nonzero finite vector x,y,z (east, north, up)");
    }
    const Eigen::Vector3d v = o.sunVector->normalized();
    return {v, "light vector " + formatNumber(v.x(), 6) + "," + formatNumber(v.y(), 6) + "," +
                   formatNumber(v.z(), 6) + " (east, north, up)"};
  }
  SunPosition sun;  // gdaldem hillshade's defaults: 315, 45
  std::string from = "-az/-alt";
  if (!o.time.empty()) {
    requireLocation(frame, o.source);
    const double jd = julianDayFromIso8601(o.time, utcOffset(o));
    sun = sunPosition(jd, frame.centreLon, frame.centreLat);
    from = "the sun at " + o.time + " seen from " + formatNumber(frame.centreLon, 5) + ", " +
           formatNumber(frame.centreLat, 5);
  } else {
    if (o.azimuth) sun.azimuth = *o.azimuth;
    if (o.altitude) sun.altitude = *o.altitude;
  }
  if (!(sun.altitude >= -90 && sun.altitude <= 90) || !std::isfinite(sun.azimuth)) {
    throw Error("altitude must be between -90 and 90 degrees and azimuth finite, got -az " +
                formatNumber(sun.azimuth) + " -alt " + formatNumber(sun.altitude));
  }
  return {frame.towardSun(sun), "azimuth " + formatNumber(sun.azimuth, 3) + " deg, altitude " +
                                    formatNumber(sun.altitude, 3) + " deg (" + from + ")"};
}

// A grey hillshade (Lambert under the same light) darkened where shadowed; nodata black.
std::vector<double> preview(const LocalFrame& f, const Eigen::Vector3d& light,
                            const std::vector<Light>& mask, const std::vector<double>* hours) {
  const int w = f.width, h = f.height;
  std::vector<double> grey(mask.size(), 0.0);
  double maxHours = 0;
  if (hours) {
    for (double x : *hours) maxHours = std::max(maxHours, x);
  }
  const auto& v = f.mesh.vertices;
  for (int r = 0; r < h; ++r) {
    for (int c = 0; c < w; ++c) {
      const std::size_t i = static_cast<std::size_t>(r) * w + c;
      if (!f.valid[i]) continue;
      const auto at = [&](int cc, int rr) -> const Eigen::Vector3d& {
        cc = std::clamp(cc, 0, w - 1), rr = std::clamp(rr, 0, h - 1);
        return v[static_cast<std::size_t>(rr) * w + cc];
      };
      const Eigen::Vector3d east = at(c + 1, r) - at(c - 1, r), north = at(c, r - 1) - at(c, r + 1);
      Eigen::Vector3d n = east.cross(north);
      const double shade = n.squaredNorm() > 0 ? std::max(0.0, n.normalized().dot(light)) : 0.5;
      if (hours) {
        grey[i] = 30 + 225 * (maxHours > 0 ? (*hours)[i] / maxHours : 0) * (0.6 + 0.4 * shade);
      } else {
        grey[i] = 40 + 215 * shade * (mask[i] == Light::Lit ? 1.0 : 0.3);
      }
    }
  }
  return grey;
}

}  // namespace

int shadow(const ShadowOptions& o, std::ostream& out, std::ostream& err) {
  try {
    if (o.output.empty()) throw Error("an output file is needed: -o OUT");
    if (lightKinds(o) > 1) throw Error("give one light: -az/-alt, --sun-vector or --time");
    if (o.hours && o.time.empty()) throw Error("--hours needs --time for the date");
    for (int v : {o.litValue, o.shadowValue, o.nodataValue}) {
      if (v < 0 || v > 255) throw Error("output values must be 0..255, got " + std::to_string(v));
    }
    const std::string format = o.format.empty() ? driverForPath(o.output) : o.format;
    const DemTerrain dem = loadDem(o.source);
    const LocalFrame frame = localFrame(dem, o.flat, o.pixelSize);
    if (!o.quiet) {
      out << "qota shadow: " << o.source << " -> " << o.output << " (" << format << ")\n"
          << "frame: " << frame.description << '\n';
    }

    std::vector<double> values(frame.mesh.vertices.size());
    std::vector<Light> mask;
    Eigen::Vector3d shownLight;
    std::vector<double> hoursLit;
    if (o.hours) {
      // Hours of direct sunlight: the sun sampled at the middle of every step of the day.
      requireLocation(frame, o.source);
      const auto [start, end, step] = *o.hours;
      if (!(step > 0) || !(end > start) || end - start > 48) {
        throw Error("--hours START END STEP: need START < END (at most 48 h apart) and STEP > 0");
      }
      const std::string date = o.time.substr(0, 10);
      std::optional<int> offset = utcOffset(o);
      if (o.time.size() > 10 && !offset) {
        // The offset written in --time, if any, applies to the whole day.
        const std::size_t p = o.time.find_first_of("Z+-", 11);
        if (p != std::string::npos) offset = parseUtcOffset(o.time.substr(p));
      }
      const double midnight = julianDayFromIso8601(date, offset);
      hoursLit.assign(values.size(), 0.0);
      const int steps = static_cast<int>(std::ceil((end - start) / step - 1e-9));
      for (int k = 0; k < steps; ++k) {
        const double t0 = start + k * step, dt = std::min(step, end - t0);
        const SunPosition sun = sunPosition(midnight + (t0 + dt / 2) / 24.0, frame.centreLon, frame.centreLat);
        if (sun.altitude <= 0) continue;
        const Eigen::Vector3d light = frame.towardSun(sun);
        mask = shadowMask(frame, light, o.terrain,
                          termProgress(o.quiet, double(k) / steps, double(k + 1) / steps), 0, o.search);
        for (std::size_t i = 0; i < mask.size(); ++i) {
          if (mask[i] == Light::Lit) hoursLit[i] += dt;
        }
      }
      for (std::size_t i = 0; i < values.size(); ++i) {
        values[i] = frame.valid[i] ? hoursLit[i] : -1.0;
      }
      if (mask.empty()) mask = shadowMask(frame, Eigen::Vector3d(0, 0, -1));  // night all day
      shownLight = frame.towardSun(sunPosition(midnight + (start + end) / 48.0, frame.centreLon, frame.centreLat));
      if (!o.quiet) {
        GDALTermProgress(1.0, "", nullptr);
        out << "sunlight: " << steps << " steps of " << formatNumber(step) << " h from "
            << formatNumber(start) << " to " << formatNumber(end) << " h local time on " << date << '\n';
      }
    } else {
      const LightChoice light = chooseLight(o, frame);
      shownLight = light.toward;
      if (!o.quiet) out << "light: " << light.description << '\n';
      if (light.toward.z() <= 0) {
        err << "qota shadow: the light is at or below the horizon: every cell is in shadow\n";
      }
      mask = shadowMask(frame, light.toward, o.terrain, termProgress(o.quiet, 0, 1), 0, o.search);
      for (std::size_t i = 0; i < mask.size(); ++i) {
        values[i] = mask[i] == Light::Lit ? o.litValue : mask[i] == Light::Shadow ? o.shadowValue : o.nodataValue;
      }
      if (!o.quiet) {
        std::size_t lit = 0, valid = 0;
        for (Light l : mask) lit += l == Light::Lit, valid += l != Light::NoData;
        const double reach = shadowReach(frame, light.toward);
        out << "lit: " << formatNumber(valid ? 100.0 * lit / valid : 0.0, 2) << " % of " << valid
            << " cells\n";
        out << "shadow reach: "
            << (std::isfinite(reach) ? formatNumber(reach, 0) + " m (" +
                                           formatNumber(reach / std::min(frame.pixelSizeX, frame.pixelSizeY), 0) +
                                           " pixels)"
                                     : std::string("unbounded"))
            << ": terrain outside the raster can shade cells this far inside it; pad tiles by that much\n";
      }
    }

    RasterWrite w{o.output, format, o.creationOptions, !o.hours, o.hours ? -1.0 : double(o.nodataValue), true};
    writeRaster(w, dem, values);
    if (!o.png.empty()) {
      const std::vector<double> grey = preview(frame, shownLight.z() > 0 ? shownLight : Eigen::Vector3d(0, 0, 1),
                                               mask, o.hours ? &hoursLit : nullptr);
      writeRaster({o.png, "PNG", {}, true, 0.0, true}, dem, grey);
    }
    if (!o.quiet) out << "written: " << o.output << (o.png.empty() ? "" : " and " + o.png) << '\n';
    return 0;
  } catch (const Error& e) {
    err << "qota shadow: " << e.what() << '\n';
    return 2;
  }
}

}  // namespace qota::tools
