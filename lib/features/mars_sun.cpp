// The Sun seen from Mars: the Mars24 algorithm (see qota/sun.hpp), step by step with the names of
// the published worked examples (A-1 ... D-6).
#include <GeographicLib/Math.hpp>

#include <algorithm>
#include <array>
#include <cmath>

#include "qota/error.hpp"
#include "qota/sun.hpp"

namespace qota {
namespace {

constexpr double kDeg = M_PI / 180.0;
constexpr double kJ2000 = 2451545.0;

double sind(double degrees) { return GeographicLib::Math::sind(degrees); }
double cosd(double degrees) { return GeographicLib::Math::cosd(degrees); }
double mod(double x, double m) {
  const double r = std::fmod(x, m);
  return r < 0 ? r + m : r;
}

// TAI - UTC from each date on (Julian day at 0h UTC of the first day it applies), IERS Bulletin C.
// No leap second has been announced after the one at the end of 2016.
struct Leap {
  double jd;
  double taiMinusUtc;
};
constexpr std::array<Leap, 28> kLeaps{{
    {2441317.5, 10}, {2441499.5, 11}, {2441683.5, 12}, {2442048.5, 13}, {2442413.5, 14}, {2442778.5, 15},
    {2443144.5, 16}, {2443509.5, 17}, {2443874.5, 18}, {2444239.5, 19}, {2444786.5, 20}, {2445151.5, 21},
    {2445516.5, 22}, {2446247.5, 23}, {2447161.5, 24}, {2447892.5, 25}, {2448257.5, 26}, {2448804.5, 27},
    {2449169.5, 28}, {2449534.5, 29}, {2450083.5, 30}, {2450630.5, 31}, {2451179.5, 32}, {2453736.5, 33},
    {2454832.5, 34}, {2456109.5, 35}, {2457204.5, 36}, {2457754.5, 37},
}};

}  // namespace

double ttMinusUtc(double julianDayUT) {
  if (!(julianDayUT >= kLeaps.front().jd)) {
    throw Error(
        "the time is before 1972, where TT - UTC is not a whole number of leap seconds; "
        "give -az/-alt or --sun-vector");
  }
  double tai = kLeaps.front().taiMinusUtc;
  for (const Leap& l : kLeaps) {
    if (julianDayUT >= l.jd) tai = l.taiMinusUtc;
  }
  return tai + 32.184;
}

double Mars24::localTrueSolarTime(double westLongitude) const {
  const double lmst = mod(meanSolarTime - westLongitude * (24.0 / 360.0), 24.0);  // C-3
  return mod(lmst + equationOfTime * (24.0 / 360.0), 24.0);                       // C-4
}

Mars24 mars24(double julianDayUT) {
  Mars24 m;
  const double jdTT = julianDayUT + ttMinusUtc(julianDayUT) / 86400.0;
  const double dt = jdTT - kJ2000;
  m.deltaJ2000 = dt;
  m.meanAnomaly = mod(19.3870 + 0.52402075 * dt, 360.0);  // B-1
  m.fmsAngle = mod(270.3863 + 0.52403840 * dt, 360.0);    // B-2
  // B-3: the perturbers (amplitude, period in Julian years, phase).
  static constexpr double kA[7] = {0.0071, 0.0057, 0.0039, 0.0037, 0.0021, 0.0020, 0.0018};
  static constexpr double kTau[7] = {2.2353, 2.7543, 1.1177, 15.7866, 2.1354, 2.4694, 32.8493};
  static constexpr double kPhi[7] = {49.409, 168.173, 191.837, 21.736, 15.704, 95.528, 49.095};
  m.perturbers = 0;
  for (int i = 0; i < 7; ++i) m.perturbers += kA[i] * cosd(0.985626 * dt / kTau[i] + kPhi[i]);
  const double M = m.meanAnomaly;
  m.equationOfCenter = (10.691 + 3.0e-7 * dt) * sind(M) + 0.623 * sind(2 * M) + 0.050 * sind(3 * M) +
                       0.005 * sind(4 * M) + 0.0005 * sind(5 * M) + m.perturbers;  // B-4
  m.ls = mod(m.fmsAngle + m.equationOfCenter, 360.0);                              // B-5
  m.equationOfTime =
      2.861 * sind(2 * m.ls) - 0.071 * sind(4 * m.ls) + 0.002 * sind(6 * m.ls) - m.equationOfCenter;  // C-1
  m.meanSolarTime = mod(24.0 * ((dt - 4.5) / 1.027491252 + 44796.0 - 0.00096), 24.0);                 // C-2
  m.subsolarWest = mod(m.meanSolarTime * (360.0 / 24.0) + m.equationOfTime + 180.0, 360.0);           // C-5
  m.declination = std::asin(0.42565 * sind(m.ls)) / kDeg + 0.25 * sind(m.ls);                         // D-1
  m.distance = 1.523679 * (1.00436 - 0.09309 * cosd(M) - 0.004336 * cosd(2 * M) - 0.00031 * cosd(3 * M) -
                           0.00003 * cosd(4 * M));  // D-2
  return m;
}

SunPosition marsSunPosition(double julianDayUT, double eastLongitude, double latitude) {
  const Mars24 m = mars24(julianDayUT);
  const double H = mod(-eastLongitude, 360.0) - m.subsolarWest;  // hour angle, west longitudes
  const double d = m.declination, phi = latitude;
  // D-5 and D-6: zenith angle and azimuth (clockwise from north).
  const double cosZ = sind(d) * sind(phi) + cosd(d) * cosd(phi) * cosd(H);
  const double zenith = std::acos(std::clamp(cosZ, -1.0, 1.0)) / kDeg;
  const double az = std::atan2(sind(H), cosd(phi) * std::tan(d * kDeg) - sind(phi) * cosd(H)) / kDeg;
  SunPosition sun;
  sun.azimuth = mod(az, 360.0);
  sun.altitude = 90.0 - zenith;
  return sun;
}

}  // namespace qota
