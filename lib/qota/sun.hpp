// Where the sun is: apparent azimuth and altitude for a place and a time, and the directions the
// shadow tools need.
//
// Algorithm: libnova (Debian's libnova-dev) computes the sun's geocentric coordinates from the
// VSOP87 planetary theory (Bretagnon & Francou 1988), referred to the J2000 equinox; qota
// precesses them to the date and applies nutation (Meeus, "Astronomical Algorithms", 2nd ed.,
// ch. 21-23, 25), and libnova transforms them to the horizon with the apparent sidereal time
// (ch. 12, 13). qota adds the sun's topocentric
// parallax (8.794 arcsec at 1 au, Meeus ch. 40) and atmospheric refraction (Saemundsson's
// formula as libnova implements it, scaled for pressure and temperature) for a sun above -1
// degree. Tested against the NREL Solar Position Algorithm's published example (Reda & Andreas
// 2004, 0.0003 degree uncertainty) and the published equinox and solstice instants: agreement
// better than 0.005 degree. Valid for any year libnova's VSOP87 covers (thousands of years).
//
// Angles in degrees. Azimuth clockwise from north (gdaldem's -az), altitude above the horizon
// (gdaldem's -alt).
#pragma once

#include <Eigen/Core>
#include <optional>
#include <string_view>

namespace qota {

struct SunPosition {
  double azimuth = 315;   // degrees clockwise from north, [0, 360)
  double altitude = 45;   // degrees above the horizon, [-90, 90]
};

struct Atmosphere {
  double pressureHpa = 1010;  // refraction scales with pressure / 1010
  double temperatureC = 10;   // and with 283 / (273 + temperature)
};

// The apparent position of the sun seen from (longitude, latitude) (degrees, east and north
// positive) at the given Julian day (UT).
SunPosition sunPosition(double julianDayUT, double longitude, double latitude,
                        const Atmosphere& atmosphere = {});

// The sun's apparent geocentric declination (degrees) at the given Julian day (UT).
double sunDeclination(double julianDayUT);

// Julian day (UT) of an ISO 8601 date and time: "YYYY-MM-DD[THH:MM[:SS[.fff]]][Z|+HH:MM|-HH:MM]"
// (a space may replace the T). Without an offset in the text, `utcOffsetMinutes` applies (local
// time = UT + offset); without either, the time is UT. Throws qota::Error naming the text.
double julianDayFromIso8601(std::string_view text, std::optional<int> utcOffsetMinutes = {});

// A UTC offset "+HH:MM", "-HH", "Z", "UTC" in minutes. Throws qota::Error naming the text.
int parseUtcOffset(std::string_view text);

// The unit vector toward the sun in a local east-north-up frame.
Eigen::Vector3d towardSunEnu(const SunPosition& sun);

}  // namespace qota
