// Where the Sun is over a shadow frame, and hours of direct sunlight over part of a day.
#pragma once

#include <cstdint>
#include <string_view>
#include <vector>

#include "qota/shadow.hpp"
#include "qota/sun.hpp"

namespace qota {

// The Sun seen from the frame's centre at a Julian day (UT): VSOP87 on the Earth, Mars24 on Mars
// (the body the DEM's CRS names). Throws qota::Error for a frame without a place (no CRS) or on
// another body, naming `source` and the other ways to give the light.
SunPosition sunOverFrame(const LocalFrame& frame, double julianDayUT, const std::string& source);

struct SunlightHours {
  std::vector<double> hours;        // per pixel: hours of direct sunlight (0 where there is no data)
  int steps = 0;                    // masks computed, night steps skipped included
  double elapsedHours = 0;          // the span's length
  std::vector<std::uint8_t> valid;  // per pixel of hours: it has data (filled by ShadowTiles only)
};

// The steps of a span between two instants (Julian days, UT), `stepHours` long (the last may be
// shorter): each step's middle and length. Throws qota::Error for a step under a minute or
// longer than the span. The one rule sunlightHours and the tiled hours (ShadowTiles) both step by.
struct SunlightStep {
  double middleJulianDay = 0;  // UT: where the Sun is taken for the whole step
  double hours = 0;
};
std::vector<SunlightStep> sunlightSteps(double startJulianDay, double endJulianDay, double stepHours);
// The checks of a window of local clock time for hours of sunlight (start and end: hours after
// local midnight, 0 <= start < end <= 48; step: at least a minute, at most end - start), before
// any work: throws qota::Error naming the values, `option` being what the caller calls them
// ("--hours", "hours").
void checkHoursWindow(double start, double end, double step, std::string_view option);
// Whether the Sun at `sun` can light any pixel of the frame: above every horizon's dip (the
// frame's horizonSlack, or a larger bound) on the ellipsoid, above the horizon on a flat frame.
bool sunCanLight(const LocalFrame& frame, const SunPosition& sun, double slack);

// Hours of direct sunlight between two instants (Julian days, UT), in steps of `stepHours`
// (the last step may be shorter): a pixel lit at a step's middle counts the whole step. Steps when
// the Sun is below the horizon of every pixel are counted without computing a mask. Throws
// qota::Error for a step under a minute or longer than the span. testOnly: as shadowMask's (the
// other pixels get 0); threads: as shadowMask's.
SunlightHours sunlightHours(const LocalFrame& frame, const std::string& source, double startJulianDay,
                            double endJulianDay, double stepHours, const IndexOptions& options = {},
                            const Progress& progress = {}, ShadowSearch search = ShadowSearch::Strips,
                            std::optional<PixelWindow> testOnly = std::nullopt, unsigned threads = 0);

}  // namespace qota
