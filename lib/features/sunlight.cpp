#include "qota/sunlight.hpp"

#include <cmath>

#include "qota/error.hpp"

namespace qota {

SunPosition sunOverFrame(const LocalFrame& frame, double julianDayUT, const std::string& source) {
  if (!frame.geographicLocation) {
    throw Error(source + ": the raster has no coordinate reference system, so its place (and the "
                "sun's position there) is unknown; give -az/-alt or --sun-vector instead");
  }
  if (frame.body.name == "Earth") return sunPosition(julianDayUT, frame.centreLon, frame.centreLat);
  if (frame.body.name == "Mars") return marsSunPosition(julianDayUT, frame.centreLon, frame.centreLat);
  throw Error(source + ": the raster lies on " + frame.body.name + "; --time knows where the Sun is "
              "seen from the Earth (VSOP87) and from Mars (Mars24) only: give the light with "
              "-az/-alt or --sun-vector");
}

SunlightHours sunlightHours(const LocalFrame& frame, const std::string& source, double startJulianDay,
                            double endJulianDay, double stepHours, const IndexOptions& options,
                            const Progress& progress, ShadowSearch search, std::optional<CellWindow> testOnly,
                            unsigned threads) {
  SunlightHours out;
  out.elapsedHours = (endJulianDay - startJulianDay) * 24.0;
  if (!(stepHours >= 1.0 / 60) || !(stepHours <= out.elapsedHours)) {
    throw Error("sunlight hours: a step of " + std::to_string(stepHours) + " h; need at least a minute and at most the span (" +
                std::to_string(out.elapsedHours) + " h)");
  }
  out.steps = static_cast<int>(std::ceil(out.elapsedHours / stepHours - 1e-9));
  out.hours.assign(frame.cellCount(), 0.0);
  const double slack = frame.horizonSlack();
  for (int k = 0; k < out.steps; ++k) {
    const double t0 = k * stepHours, dt = std::min(stepHours, out.elapsedHours - t0);
    const SunPosition sun = sunOverFrame(frame, startJulianDay + (t0 + dt / 2) / 24.0, source);
    if (sun.altitude <= -slack || (!frame.body.ellipsoid && sun.altitude <= 0)) continue;  // night everywhere
    const Progress part = progress ? Progress([&, k](double done, const char* message) {
      return progress((k + done) / out.steps, message);
    })
                                   : Progress();
    const std::vector<Light> mask = shadowMask(frame, frame.towardSun(sun), options, part, threads, search, testOnly);
    for (std::size_t i = 0; i < mask.size(); ++i) {
      if (mask[i] == Light::Lit) out.hours[i] += dt;
    }
  }
  return out;
}

}  // namespace qota
