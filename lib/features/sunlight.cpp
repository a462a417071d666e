#include "qota/sunlight.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <string>

#include "qota/error.hpp"
#include "qota/memory_budget.hpp"

namespace qota {

SunPosition sunOverFrame(const LocalFrame& frame, double julianDayUT, const std::string& source) {
  if (!frame.geographicLocation) {
    throw Error(source +
                ": the raster has no coordinate reference system, so its place (and the "
                "sun's position there) is unknown; give -az/-alt or --sun-vector instead");
  }
  if (frame.body.name == "Earth") return sunPosition(julianDayUT, frame.centreLon, frame.centreLat);
  if (frame.body.name == "Mars") return marsSunPosition(julianDayUT, frame.centreLon, frame.centreLat);
  throw Error(source + ": the raster lies on " + frame.body.name +
              "; --time knows where the Sun is "
              "seen from the Earth (VSOP87) and from Mars (Mars24) only: give the light with "
              "-az/-alt or --sun-vector");
}

std::vector<SunlightStep> sunlightSteps(double startJulianDay, double endJulianDay, double stepHours) {
  const double elapsed = (endJulianDay - startJulianDay) * 24.0;
  // (a span from Julian days carries their rounding, some 1e-8 h: a step equal to the span as
  // given is that span, not more)
  constexpr double kSpanRounding = 1e-6;
  if (!(stepHours >= 1.0 / 60) || !(stepHours <= elapsed + kSpanRounding)) {
    throw Error("sunlight hours: a step of " + std::to_string(stepHours) +
                " h; need at least a minute and at most the span (" + std::to_string(elapsed) + " h)");
  }
  const int steps = std::max(1, static_cast<int>(std::ceil((elapsed - kSpanRounding) / stepHours)));
  std::vector<SunlightStep> out(static_cast<std::size_t>(steps));
  for (int k = 0; k < steps; ++k) {
    const double t0 = k * stepHours, dt = std::min(stepHours, elapsed - t0);
    out[static_cast<std::size_t>(k)] = {startJulianDay + (t0 + dt / 2) / 24.0, dt};
  }
  return out;
}

namespace {

std::string shortest(double v) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

}  // namespace

void checkHoursWindow(double start, double end, double step, std::string_view option) {
  const std::string name(option);
  if (!(start >= 0) || !(end > start) || !(end <= 48)) {
    throw Error(name + " START END STEP: need 0 <= START < END <= 48 (hours after local midnight), got " +
                shortest(start) + " " + shortest(end));
  }
  if (!(step >= 1.0 / 60) || !(step <= end - start)) {
    throw Error(name + " STEP " + shortest(step) + ": need at least one minute (1/60 h) and at most END - START (" +
                shortest(end - start) + " h)");
  }
}

bool sunCanLight(const LocalFrame& frame, const SunPosition& sun, double slack) {
  return sun.altitude > -slack && (frame.body.ellipsoid || sun.altitude > 0);
}

SunlightHours sunlightHours(const LocalFrame& frame, const std::string& source, double startJulianDay,
                            double endJulianDay, double stepHours, const IndexOptions& options,
                            const Progress& progress, ShadowSearch search, std::optional<PixelWindow> testOnly,
                            unsigned threads) {
  SunlightHours out;
  out.elapsedHours = (endJulianDay - startJulianDay) * 24.0;
  const std::vector<SunlightStep> steps = sunlightSteps(startJulianDay, endJulianDay, stepHours);
  out.steps = static_cast<int>(steps.size());
  out.hours.assign(frame.pixelCount(), 0.0);
  const double slack = frame.horizonSlack();
  for (int k = 0; k < out.steps; ++k) {
    const SunlightStep& step = steps[static_cast<std::size_t>(k)];
    const SunPosition sun = sunOverFrame(frame, step.middleJulianDay, source);
    if (!sunCanLight(frame, sun, slack)) continue;  // night everywhere
    const Progress part =
        progress
            ? Progress([&, k](double done, const char* message) { return progress((k + done) / out.steps, message); })
            : Progress();
    const std::vector<Light> mask = shadowMask(frame, frame.towardSun(sun), options, part, threads, search, testOnly);
    for (std::size_t i = 0; i < mask.size(); ++i) {
      if (mask[i] == Light::Lit) out.hours[i] += step.hours;
    }
    memory::releaseFreedMemory();  // (else the peak grows with the steps: 68 MiB over one on Rainier)
  }
  return out;
}

}  // namespace qota
