// qota shadow: a directional light's shadows on a DEM (see qota_tools.hpp and qota/shadow.hpp).
#include <Eigen/Geometry>
#include <gdal_priv.h>

#include <cmath>
#include <filesystem>
#include <iostream>

#include "qota/enu.hpp"
#include "qota/error.hpp"
#include "qota/instant.hpp"
#include "qota/mapping_registry.hpp"
#include "qota/shadow.hpp"
#include "qota/sunlight.hpp"
#include "qota/viewshed.hpp"
#include "cancel.hpp"
#include "preview.hpp"
#include "qota_tools.hpp"
#include "raster_output.hpp"
#include "shadow_parts.hpp"
#include "text_output.hpp"

namespace qota::tools {

Progress termProgress(bool quiet, double lo, double hi) {
  if (quiet) return [](double, const char*) { return !cancelRequested(); };
  return [lo, hi](double done, const char* message) {
    return GDALTermProgress(lo + (hi - lo) * done, message, nullptr) != FALSE && !cancelRequested();
  };
}

namespace {

int lightKinds(const ShadowOptions& o) {
  return (o.azimuth || o.altitude ? 1 : 0) + (o.sunVector ? 1 : 0) + (o.time.empty() ? 0 : 1) +
         (o.sunVectorBody ? 1 : 0) + (o.subsolar ? 1 : 0) + (o.lightPoint ? 1 : 0);
}

// East, north and up at (lon, lat) on the frame's body, or the refusal where they are undefined.
EnuMapping enuAt(const LocalFrame& frame, double lon, double lat, const std::string& what) {
  if (!frame.geographicLocation) {
    throw Error(what + " needs the DEM on its body (a CRS): this raster has none");
  }
  if (!(std::fabs(lat) <= 90) || !std::isfinite(lon)) {
    throw Error(what + ": longitude " + formatNumber(lon) + ", latitude " + formatNumber(lat) + " is no place");
  }
  return EnuMapping(lat, lon, 0.0, frame.body.a > 0 ? frame.body.a : 6378137.0,
                    frame.body.a > 0 ? 1 - frame.body.b / frame.body.a : 1 / 298.257223563);
}

// The frame's direction of a vector in the body-fixed, body-centred frame.
Eigen::Vector3d fromBody(const LocalFrame& frame, const Eigen::Vector3d& v) {
  const Eigen::Vector3d d = v.normalized();
  if (frame.body.ellipsoid) return frame.body.rotation * d;
  // A flat frame: the direction's azimuth and altitude at the centre, turned to grid north.
  const EnuMapping enu = enuAt(frame, frame.centreLon, frame.centreLat, "a body vector");
  SunPosition s;
  s.azimuth = std::atan2(d.dot(enu.east()), d.dot(enu.north())) * 180 / M_PI;
  s.altitude = std::asin(std::clamp(d.dot(enu.up()), -1.0, 1.0)) * 180 / M_PI;
  return frame.towardSun(s);
}

std::string vectorText(const Eigen::Vector3d& v) {
  return formatNumber(v.x(), 9) + "," + formatNumber(v.y(), 9) + "," + formatNumber(v.z(), 9);
}

}  // namespace

LightChoice chooseLight(const ShadowOptions& o, const LocalFrame& frame, std::ostream& out) {
  // East-north-up at the centre is undefined at a pole: what is given in it is refused there.
  // (A flat frame takes its grid's own north, as it takes the grid itself.)
  const bool atPole = frame.body.ellipsoid && std::fabs(frame.centreLat) > 90 - kPoleDegrees;
  const auto poleRefused = [&](const std::string& what) {
    throw Error(
        what + " are east-north-up at the DEM's centre, " + formatNumber(frame.centreLon, 6) + ", " +
        formatNumber(frame.centreLat, 6) + ", within " + formatNumber(kPoleDegrees) +
        " degrees of a pole, where east and north are undefined; give the light in the body's own frame "
        "(--sun-vector-body X,Y,Z or --subsolar LON,LAT), or -az/-alt at a place away from the pole (--at LON,LAT)");
  };
  if (o.at && !(o.azimuth || o.altitude)) throw Error("--at is where -az/-alt are east-north-up; give them with it");
  if (o.sunVectorBody || o.subsolar) {
    Eigen::Vector3d v;
    std::string said;
    if (o.sunVectorBody) {
      if (!o.sunVectorBody->allFinite() || o.sunVectorBody->squaredNorm() == 0) {
        throw Error("--sun-vector-body must be a nonzero finite vector x,y,z (body-fixed, body-centred)");
      }
      v = *o.sunVectorBody;
      said = "body-fixed sun vector " + vectorText(v.normalized());
    } else {
      const auto [lon, lat] = *o.subsolar;
      if (!(std::fabs(lat) <= 90) || !std::isfinite(lon)) {
        throw Error("--subsolar " + formatNumber(lon) + "," + formatNumber(lat) +
                    ": give the sub-solar longitude and "
                    "latitude (degrees, latitude in [-90, 90])");
      }
      const double c = std::cos(lat * M_PI / 180);
      v = Eigen::Vector3d(c * std::cos(lon * M_PI / 180), c * std::sin(lon * M_PI / 180), std::sin(lat * M_PI / 180));
      said = "the Sun over " + formatNumber(lon, 6) + ", " + formatNumber(lat, 6) + " (sub-solar point)";
    }
    if (!frame.geographicLocation) throw Error("--sun-vector-body and --subsolar need the DEM on its body (a CRS)");
    const Eigen::Vector3d toward = fromBody(frame, v);
    return {toward, said + "; toward " + vectorText(toward) + " in the frame"};
  }
  if (o.sunVector) {
    if (!o.sunVector->allFinite() || o.sunVector->squaredNorm() == 0) {
      throw Error("--sun-vector must be a nonzero finite vector x,y,z (east, north, up)");
    }
    if (atPole) poleRefused("--sun-vector's east, north and up");
    const Eigen::Vector3d v = o.sunVector->normalized();
    return {v, "light vector " + formatNumber(v.x(), 6) + "," + formatNumber(v.y(), 6) + "," + formatNumber(v.z(), 6) +
                   " (east, north, up at the centre)"};
  }
  SunPosition sun;  // gdaldem hillshade's defaults: 315, 45
  std::string from = "-az/-alt";
  if (!o.time.empty()) {
    const Instant t = parseInstant(o.time, o.tz);
    if (!o.quiet) out << "time: " << t.local << " = " << t.utc << '\n';
    sun = sunOverFrame(frame, t.julianDayUT, o.source);
    from = "the Sun at " + t.utc + " seen from " + formatNumber(frame.centreLon, 5) + ", " +
           formatNumber(frame.centreLat, 5) + " on " + frame.body.name;
  } else {
    if (o.azimuth) sun.azimuth = *o.azimuth;
    if (o.altitude) sun.altitude = *o.altitude;
  }
  if (!(sun.altitude >= -90 && sun.altitude <= 90) || !std::isfinite(sun.azimuth)) {
    throw Error("altitude must be between -90 and 90 degrees and azimuth finite, got -az " + formatNumber(sun.azimuth) +
                " -alt " + formatNumber(sun.altitude));
  }
  if (o.time.empty() && o.at) {
    // East-north-up at the place given: the same light, seen from the frame.
    const auto [lon, lat] = *o.at;
    const EnuMapping enu = enuAt(frame, lon, lat, "--at");
    if (std::fabs(lat) > 90 - kPoleDegrees)
      poleRefused("-az/-alt at --at " + formatNumber(lon) + "," + formatNumber(lat));
    const Eigen::Vector3d local = towardSunEnu(sun);
    const Eigen::Vector3d body = local.x() * enu.east() + local.y() * enu.north() + local.z() * enu.up();
    const Eigen::Vector3d toward = fromBody(frame, body);
    return {toward, "azimuth " + formatNumber(sun.azimuth, 3) + " deg, altitude " + formatNumber(sun.altitude, 3) +
                        " deg at " + formatNumber(lon, 6) + ", " + formatNumber(lat, 6) + "; toward " +
                        vectorText(toward) + " in the frame"};
  }
  if (o.time.empty() && atPole) poleRefused("-az/-alt");
  return {frame.towardSun(sun), "azimuth " + formatNumber(sun.azimuth, 3) + " deg, altitude " +
                                    formatNumber(sun.altitude, 3) + " deg (" + from + ")"};
}

LocalSpan hoursSpan(const ShadowOptions& o) {
  // Hours of direct sunlight: the elapsed time between the local clock times START and END of
  // the date, in steps of STEP hours; a pixel lit at a step's middle counts the whole step.
  const auto [start, end, step] = *o.hours;
  checkHoursWindow(start, end, step, "--hours");
  return localSpan(o.time, o.tz, start, end);
}

namespace {

// The preview: the mask in colour over a hillshade lit from the light (from overhead when it is
// down), with a legend; or the hours on a colour ramp with its scale.
void writePreview(const ShadowOptions& o, const LocalFrame& frame, const Eigen::Vector3d& light,
                  const std::vector<Light>& mask, const std::vector<double>& hours, const std::string& title,
                  OutputStage& stage) {
  const std::vector<double> shade = hillshade(frame, light.z() > 0 ? light.normalized() : Eigen::Vector3d(0, 0, 1));
  if (o.hours) {
    std::vector<double> values(hours.size());
    double most = 0;
    for (std::size_t i = 0; i < values.size(); ++i) {
      values[i] = frame.valid[i] ? hours[i] : std::numeric_limits<double>::quiet_NaN();
      if (frame.valid[i]) most = std::max(most, hours[i]);
    }
    writeRampPreview(o.png, frame.width, frame.height, shade, values, 0, most, "h", title, stage);
    return;
  }
  std::vector<int> classes(mask.size());
  for (std::size_t i = 0; i < mask.size(); ++i) {
    classes[i] = mask[i] == Light::Lit ? 0 : mask[i] == Light::Shadow ? 1 : -1;
  }
  writeCategoryPreview(o.png, frame.width, frame.height, shade, classes,
                       {{"lit", {255, 255, 255}, 0.0}, {"in shadow", {40, 80, 220}, 0.6}}, title, stage);
}

}  // namespace

bool sameFile(const std::string& a, const std::string& b) {
  std::error_code ec;
  if (std::filesystem::equivalent(a, b, ec)) return true;
  return std::filesystem::weakly_canonical(a, ec) == std::filesystem::weakly_canonical(b, ec) && !ec;
}

// Everything that can be refused before any work: the light, the values, the outputs.
void checkOptions(const ShadowOptions& o, const std::string& format) {
  if (o.output.empty()) throw Error("an output file is needed: -o OUT");
  if (lightKinds(o) > 1) {
    throw Error("give one light: -az/-alt, --sun-vector, --time, --sun-vector-body, --subsolar or --light-point");
  }
  if (o.lightPointAbsolute && !o.lightPoint) throw Error("--light-point-absolute needs --light-point");
  if (!o.tz.empty() && o.time.empty()) throw Error("--tz needs --time (the date and time it is the zone of)");
  if (o.hours && o.time.empty()) throw Error("--hours needs --time for the date");
  for (int v : {o.litValue, o.shadowValue, o.nodataValue}) {
    if (v < 0 || v > 255) throw Error("output values must be 0..255, got " + std::to_string(v));
  }
  if (!o.hours && (o.litValue == o.shadowValue || o.litValue == o.nodataValue || o.shadowValue == o.nodataValue)) {
    throw Error("--lit-value " + std::to_string(o.litValue) + ", --shadow-value " + std::to_string(o.shadowValue) +
                " and --nodata-value " + std::to_string(o.nodataValue) +
                " must differ, or lit, shadow and nodata pixels could not be told apart");
  }
  if (format == "VRT" || format == "MEM") {
    throw Error(o.output + ": the " + format +
                " format holds no pixels of its own (it would point at "
                "a dataset that is gone); write a GeoTIFF (.tif) or another format that stores them");
  }
  for (const std::string* path : {&o.output, &o.png}) {
    if (!path->empty() && sameFile(*path, o.source)) {
      throw Error(*path + " is the input DEM; give another output name");
    }
  }
  if (!o.png.empty() && sameFile(o.png, o.output)) throw Error("--png and -o name the same file");
}

namespace {

ShadowOptions withMappingRead(const ShadowOptions& given) {
  ShadowOptions o = given;
  o.flat = flatByMapping(o.mapping, o.flat, "shadow", "casts no parallel light on a DEM's grid");
  return o;
}

}  // namespace

bool flatByMapping(const std::string& mapping, bool flat, const char* tool, const char* others) {
  if (mapping.empty()) return flat;
  const MappingEntry& entry = mappingEntry(mapping);  // (an unknown name is refused with the list)
  if (entry.map) return true;
  if (entry.ellipsoidHeights) {
    if (flat) throw Error("--mapping " + mapping + " puts the DEM on its ellipsoid; --flat keeps it flat: give one");
    return false;
  }
  throw Error("--mapping " + mapping + ": qota " + tool + " places a DEM on its ellipsoid (" +
              mappingsWith(&MappingEntry::ellipsoidHeights) + ", the default) or flat (" +
              mappingsWith(&MappingEntry::map) + "); the " + mapping + " mapping " + others);
}

std::vector<std::pair<std::string, std::string>> shadowProvenance(const ShadowOptions& o, int band,
                                                                  const std::string& frame, const std::string& light) {
  std::vector<std::pair<std::string, std::string>> items{{"QOTA_TOOL", "shadow"},
                                                         {"QOTA_SOURCE", o.source},
                                                         {"QOTA_BAND", std::to_string(band)},
                                                         {"QOTA_FRAME", frame},
                                                         {"QOTA_LIGHT", light}};
  if (o.fillVoids) items.emplace_back("QOTA_FILL_VOIDS", kFillVoidsText);
  if (!o.time.empty()) items.emplace_back("QOTA_TIME", o.time);
  if (!o.tz.empty()) items.emplace_back("QOTA_TZ", o.tz);
  if (o.hours) {
    items.emplace_back("QOTA_HOURS", "start " + formatNumber((*o.hours)[0]) + " h, end " + formatNumber((*o.hours)[1]) +
                                         " h, step " + formatNumber((*o.hours)[2]) + " h (local clock)");
  }
  items.emplace_back("QOTA_VALUES", o.hours ? std::string("hours of direct sunlight, nodata -1")
                                            : "lit " + std::to_string(o.litValue) + ", shadow " +
                                                  std::to_string(o.shadowValue) + ", nodata " +
                                                  std::to_string(o.nodataValue));
  return items;
}

int shadow(const ShadowOptions& given, std::ostream& out, std::ostream& err) {
  try {
    const ShadowOptions o = withMappingRead(given);
    for (const std::string* path : {&o.output, &o.png}) {
      if (!path->empty()) OutputStage::checkTarget(*path);
    }
    const std::string format = o.output.empty() ? "" : o.format.empty() ? driverForPath(o.output) : o.format;
    checkOptions(o, format);
    const int mostValue = std::max({o.litValue, o.shadowValue, o.nodataValue});
    for (const std::string& warning : checkCreationOptions(format, o.creationOptions, !o.hours, mostValue)) {
      err << "qota shadow: warning: GDAL: " << warning << '\n';
    }
    const std::uint64_t resident = memory::residentBytes();
    if (o.lightPoint && (o.tileSize > 0 || o.tile || !o.tilesState.empty())) {
      throw Error("--light-point shades the whole raster in memory; it does not run by tiles");
    }
    if (!o.lightPoint && runsByTiles(o)) {
      if (o.fillVoids) {
        throw Error(
            "--fill-voids fills the whole raster in memory; by tiles, fill it first (gdal_fillnodata) and "
            "give the filled raster");
      }
      return shadowByTiles(o, format, out, err);
    }
    const std::uint64_t estimate = o.lightPoint ? 0 : wholeEstimate(o, resident);
    DemOptions demOptions;
    demOptions.band = o.band;
    demOptions.lonLatAsCartesian = true;  // read as lon/lat: the frame puts it on its ellipsoid
    // (A point light inside the outermost pixel centres is walked, with no quadtree; one outside
    // is checked again before its quadtree is built.)
    demOptions.then = o.lightPoint ? memory::kWalkedLight : memory::kShadow;
    demOptions.fillVoids = o.fillVoids ? kFillVoidsPixels : 0;
    refuseBeyondMaxPixels(o, describeDem(o.source, demOptions));
    const DemTerrain dem = loadDem(o.source, demOptions);
    const LocalFrame frame = localFrame(dem, frameOptionsOf(o));
    if (!o.quiet) {
      out << "qota shadow: " << o.source << " -> " << o.output << " (" << format << ")\n"
          << "frame: " << frame.description << '\n';
      if (o.fillVoids) {
        out << "voids: " << dem.filledPixels << " pixels filled (GDAL's fill-nodata), " << dem.nodataPixels
            << " left\n";
      }
      if (frame.metresPerUnit != 1) {
        out << "heights: " << formatNumber(frame.metresPerUnit) << " m per unit ("
            << (dem.verticalUnit.known() ? "'" + dem.verticalUnit.name + "'" : std::string("-s")) +
                   (o.zFactor != 1 ? ", -z " + formatNumber(o.zFactor) : std::string())
            << ")\n";
      }
    }

    const std::size_t pixels = frame.pixelCount();
    std::vector<double> values(pixels);
    std::vector<Light> mask;
    Eigen::Vector3d shownLight;
    std::vector<double> hoursLit;
    std::string lightText;   // the light, for the output's provenance
    std::string lightTitle;  // and in short, for the preview
    if (o.hours) {
      const double step = (*o.hours)[2];
      const LocalSpan span = hoursSpan(o);
      const SunlightHours sunlight = sunlightHours(frame, o.source, span.start.julianDayUT, span.end.julianDayUT, step,
                                                   o.index, termProgress(o.quiet, 0, 1), o.search);
      hoursLit = sunlight.hours;
      for (std::size_t i = 0; i < pixels; ++i) values[i] = frame.valid[i] ? hoursLit[i] : -1.0;
      shownLight = frame.towardSun(sunOverFrame(frame, (span.start.julianDayUT + span.end.julianDayUT) / 2, o.source));
      const int steps = sunlight.steps;
      const double elapsed = sunlight.elapsedHours;
      lightText = "sunlight hours from " + span.start.local + " (" + span.start.utc + ") to " + span.end.local + " (" +
                  span.end.utc + ") in " + std::to_string(steps) + " steps of " + formatNumber(step) + " h";
      lightTitle = "hours of direct sunlight from " + span.start.local + " to " + span.end.local + ", steps of " +
                   formatNumber(step) + " h";
      if (!o.quiet) {
        GDALTermProgress(1.0, "", nullptr);
        out << "sunlight: " << steps << " steps of " << formatNumber(step) << " h, from " << span.start.local << " ("
            << span.start.utc << ") to " << span.end.local << " (" << span.end.utc << "), " << formatHours(elapsed)
            << " h\n";
      }
    } else if (o.lightPoint) {
      PointLightOptions p;
      p.x = (*o.lightPoint)[0], p.y = (*o.lightPoint)[1], p.height = (*o.lightPoint)[2];
      p.aboveSurface = !o.lightPointAbsolute;
      p.frame = frameOptionsOf(o);
      p.index = o.index;
      lightText = "a point at " + formatNumber(p.x) + "," + formatNumber(p.y) + ", " + formatNumber(p.height) + " m " +
                  (p.aboveSurface ? "above the surface" : "over the DEM's reference");
      lightTitle = "shadows of " + lightText;
      if (!o.quiet) {
        out << "light: a point at " << formatNumber(p.x) << ", " << formatNumber(p.y) << ", " << formatNumber(p.height)
            << " m " << (p.aboveSurface ? "above the surface" : "over the DEM's reference") << '\n';
      }
      mask = pointLightMask(dem, p, termProgress(o.quiet, 0, 1));
      for (std::size_t i = 0; i < pixels; ++i) {
        values[i] = mask[i] == Light::Lit ? o.litValue : mask[i] == Light::Shadow ? o.shadowValue : o.nodataValue;
      }
      shownLight = Eigen::Vector3d(0, 0, 1);
      if (!o.quiet) {
        std::size_t lit = 0, valid = 0;
        for (Light l : mask) lit += l == Light::Lit, valid += l != Light::NoData;
        out << "lit: " << formatNumber(valid ? 100.0 * lit / valid : 0.0, 2) << " % of " << valid << " pixels\n";
      }
    } else {
      const LightChoice light = chooseLight(o, frame, out);
      shownLight = light.toward;
      lightText = light.description + "; toward " + formatNumber(light.toward.x()) + "," +
                  formatNumber(light.toward.y()) + "," + formatNumber(light.toward.z()) + " in the frame";
      lightTitle = "shadows, light at " + light.description;
      if (!o.quiet) out << "light: " << light.description << '\n';
      if (light.toward.z() <= 0) {
        err << "qota shadow: the light is at or below the horizon at the centre"
            << (frame.body.ellipsoid ? "" : ": every pixel is in shadow") << '\n';
      }
      mask = shadowMask(frame, light.toward, o.index, termProgress(o.quiet, 0, 1), 0, o.search);
      for (std::size_t i = 0; i < pixels; ++i) {
        values[i] = mask[i] == Light::Lit ? o.litValue : mask[i] == Light::Shadow ? o.shadowValue : o.nodataValue;
      }
      if (!o.quiet) {
        std::size_t lit = 0, valid = 0;
        for (Light l : mask) lit += l == Light::Lit, valid += l != Light::NoData;
        const double reach = shadowReach(frame, light.toward);
        out << "lit: " << formatNumber(valid ? 100.0 * lit / valid : 0.0, 2) << " % of " << valid << " pixels\n";
        out << "shadow reach: "
            << (std::isfinite(reach)
                    ? formatReadable(reach, 0) + " m (" +
                          formatReadable(reach / std::min(frame.pixelSizeX, frame.pixelSizeY), 0) + " pixels)"
                    : std::string("unbounded"))
            << ": terrain outside the raster can shade pixels this far inside it; pad tiles by that much\n";
      }
    }

    // Both outputs staged, then placed together: a failing preview leaves no mask either.
    OutputStage stage;
    RasterWrite w{o.output,
                  format,
                  o.creationOptions,
                  !o.hours,
                  o.hours ? -1.0 : double(o.nodataValue),
                  true,
                  shadowProvenance(o, dem.band, frame.description, lightText)};
    w.bandDescription = o.hours ? "hours of direct sunlight" : "shadow mask";
    w.bandUnit = o.hours ? "h" : "";
    writeRaster(w, dem, values, stage);
    if (!o.png.empty()) {
      writePreview(o, frame, shownLight, mask, hoursLit,
                   std::filesystem::path(o.source).filename().string() + ": " + lightTitle, stage);
    }
    stage.commit();
    if (!o.quiet) {
      out << "written: " << o.output << (o.png.empty() ? "" : " and " + o.png) << '\n'
          << "memory: peak " << memory::peakBytes() / (1 << 20) << " MiB"
          << (estimate ? " (estimated " + std::to_string(estimate / (1 << 20)) + " MiB)" : std::string()) << '\n';
    }
    return 0;
  } catch (...) {
    return reportFailure("shadow", err);
  }
}

}  // namespace qota::tools
