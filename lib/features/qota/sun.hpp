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
// On Mars the Sun comes from the Mars24 algorithm (Allison & McEwen 2000, as documented with
// worked examples by NASA GISS, "Mars24 Algorithm and Worked Examples", 2015 revision): the
// areocentric solar longitude Ls, the equation of time, mean solar time at the prime meridian and
// the subsolar point, from which the direction of the Sun follows at any place. Tested against
// both published worked examples (to 1e-4 degree, 1e-5 hour). Times are UTC; TT - UTC comes from
// the leap-second table (1972 onwards).
//
// Angles in degrees. Azimuth clockwise from north (gdaldem's -az), altitude above the horizon
// (gdaldem's -alt).
#pragma once

#include <Eigen/Core>

namespace qota {

struct SunPosition {
  double azimuth = 315;  // degrees clockwise from north, [0, 360)
  double altitude = 45;  // degrees above the horizon, [-90, 90]
};

struct Atmosphere {
  double pressureHpa = 1010;  // refraction scales with pressure / 1010
  double temperatureC = 10;   // and with 283 / (273 + temperature)
};

// The apparent position of the sun seen from (longitude, latitude) (degrees, east and north
// positive) at the given Julian day (UT).
SunPosition sunPosition(double julianDayUT, double longitude, double latitude, const Atmosphere& atmosphere = {});

// The sun's apparent geocentric declination (degrees) at the given Julian day (UT).
double sunDeclination(double julianDayUT);

// The Sun from Mars by the Mars24 algorithm: every intermediate of the published worked examples.
struct Mars24 {
  double deltaJ2000 = 0;        // days (TT) since J2000
  double meanAnomaly = 0;       // B-1, degrees
  double fmsAngle = 0;          // B-2: the fictitious mean sun's angle, degrees
  double perturbers = 0;        // B-3, degrees
  double equationOfCenter = 0;  // B-4: true minus mean anomaly, degrees
  double ls = 0;                // B-5: areocentric solar longitude, degrees [0, 360)
  double equationOfTime = 0;    // C-1, degrees
  double meanSolarTime = 0;     // C-2: at the prime meridian (Airy-0), hours [0, 24)
  double subsolarWest = 0;      // C-5: west longitude of the subsolar point, degrees [0, 360)
  double declination = 0;       // D-1: planetocentric declination of the Sun, degrees
  double distance = 0;          // D-2: heliocentric distance, au
  // C-4: local true solar time at a west longitude, hours [0, 24).
  double localTrueSolarTime(double westLongitude) const;
};
Mars24 mars24(double julianDayUT);

// The Sun seen from (east longitude, latitude) on Mars: azimuth clockwise from north and altitude
// (90 degrees minus Mars24's zenith angle, D-5 and D-6). No refraction: Mars's thin atmosphere
// bends light by far less than the algorithm's accuracy.
SunPosition marsSunPosition(double julianDayUT, double eastLongitude, double latitude);

// TT - UTC in seconds at a Julian day (UTC): 32.184 s plus the leap seconds (TAI - UTC, 10 s in
// 1972 to 37 s since 2017). Throws qota::Error before 1972, where UTC had no whole-second steps.
double ttMinusUtc(double julianDayUT);

// The unit vector toward the sun in a local east-north-up frame.
Eigen::Vector3d towardSunEnu(const SunPosition& sun);

}  // namespace qota
