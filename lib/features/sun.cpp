#include "qota/sun.hpp"

#include <libnova/julian_day.h>
#include <libnova/nutation.h>
#include <libnova/precession.h>
#include <libnova/refraction.h>
#include <libnova/solar.h>
#include <libnova/transform.h>

#include <cmath>

#include "qota/error.hpp"

namespace qota {
namespace {

constexpr double kDeg = M_PI / 180.0;

// The sun's apparent right ascension and declination referred to the true equator and equinox of
// the date. libnova's solar coordinates are referred to the J2000 equinox (they are 0.33 degree
// off in 2024 otherwise), so they are precessed to the date and corrected for nutation
// (Meeus eq. 23.1; libnova's IAU 1980 nutation).
ln_equ_posn apparentEquatorial(double jd) {
  ln_equ_posn j2000{}, mean{};
  ln_get_solar_equ_coords(jd, &j2000);
  ln_get_equ_prec(&j2000, jd, &mean);
  ln_nutation nut{};
  ln_get_nutation(jd, &nut);
  const double eps = (nut.ecliptic + nut.obliquity) * kDeg, a = mean.ra * kDeg, d = mean.dec * kDeg;
  ln_equ_posn out = mean;
  out.ra += (std::cos(eps) + std::sin(eps) * std::sin(a) * std::tan(d)) * nut.longitude -
            std::cos(a) * std::tan(d) * nut.obliquity;
  out.dec += std::sin(eps) * std::cos(a) * nut.longitude + std::sin(a) * nut.obliquity;
  return out;
}

}  // namespace

double sunDeclination(double julianDayUT) { return apparentEquatorial(julianDayUT).dec; }

SunPosition sunPosition(double julianDayUT, double longitude, double latitude, const Atmosphere& atmosphere) {
  ln_equ_posn equ = apparentEquatorial(julianDayUT);
  ln_lnlat_posn observer{longitude, latitude};
  ln_hrz_posn hrz{};
  ln_get_hrz_from_equ(&equ, &observer, julianDayUT, &hrz);
  SunPosition sun;
  sun.azimuth = std::fmod(hrz.az + 180.0, 360.0);  // libnova counts from south, westward
  double alt = hrz.alt;
  alt -= 8.794 / 3600.0 * std::cos(alt * kDeg);  // parallax: the observer is not at the centre
  if (alt > -1.0) alt += ln_get_refraction_adj(alt, atmosphere.pressureHpa, atmosphere.temperatureC);
  sun.altitude = alt;
  return sun;
}

Eigen::Vector3d towardSunEnu(const SunPosition& sun) {
  const double az = sun.azimuth * kDeg, alt = sun.altitude * kDeg;
  return {std::sin(az) * std::cos(alt), std::cos(az) * std::cos(alt), std::sin(alt)};
}

}  // namespace qota
