#include "qota/sun.hpp"

#include <libnova/julian_day.h>
#include <libnova/nutation.h>
#include <libnova/precession.h>
#include <libnova/refraction.h>
#include <libnova/solar.h>
#include <libnova/transform.h>

#include <charconv>
#include <cmath>
#include <string>

#include "qota/error.hpp"

namespace qota {
namespace {

constexpr double kDeg = M_PI / 180.0;

// Parses digits [pos, pos + n) as an integer; false when they are not all digits.
bool digits(std::string_view s, std::size_t pos, std::size_t n, int& out) {
  if (pos + n > s.size()) return false;
  for (std::size_t i = pos; i < pos + n; ++i) {
    if (s[i] < '0' || s[i] > '9') return false;
  }
  return std::from_chars(s.data() + pos, s.data() + pos + n, out).ec == std::errc();
}

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

[[noreturn]] void badTime(std::string_view text, const char* why) {
  throw Error("time '" + std::string(text) + "': " + why +
              " (expected YYYY-MM-DDTHH:MM[:SS][Z|+HH:MM])");
}

}  // namespace

int parseUtcOffset(std::string_view text) {
  if (text == "Z" || text == "UTC" || text == "z") return 0;
  int h = 0, m = 0;
  if (text.size() >= 3 && (text[0] == '+' || text[0] == '-') && digits(text, 1, 2, h)) {
    std::size_t pos = 3;
    if (pos < text.size() && text[pos] == ':') ++pos;
    if (pos < text.size() && !digits(text, pos, 2, m)) pos = std::string_view::npos;
    if (pos != std::string_view::npos && (pos == text.size() || pos + 2 == text.size()) && h <= 18 &&
        m < 60) {
      return (text[0] == '-' ? -1 : 1) * (h * 60 + m);
    }
  }
  throw Error("UTC offset '" + std::string(text) + "': expected Z, +HH:MM or -HH:MM");
}

double julianDayFromIso8601(std::string_view text, std::optional<int> utcOffsetMinutes) {
  int year = 0, month = 0, day = 0, hour = 0, minute = 0;
  double second = 0;
  if (!digits(text, 0, 4, year) || text.size() < 10 || text[4] != '-' || !digits(text, 5, 2, month) ||
      text[7] != '-' || !digits(text, 8, 2, day)) {
    badTime(text, "not a date");
  }
  std::size_t pos = 10;
  if (pos < text.size() && (text[pos] == 'T' || text[pos] == ' ')) {
    if (!digits(text, pos + 1, 2, hour) || pos + 3 >= text.size() || text[pos + 3] != ':' ||
        !digits(text, pos + 4, 2, minute)) {
      badTime(text, "not a time of day");
    }
    pos += 6;
    if (pos < text.size() && text[pos] == ':') {
      std::size_t end = pos + 1;
      while (end < text.size() && ((text[end] >= '0' && text[end] <= '9') || text[end] == '.')) ++end;
      const auto r = std::from_chars(text.data() + pos + 1, text.data() + end, second);
      if (r.ec != std::errc() || r.ptr != text.data() + end || second >= 61) badTime(text, "bad seconds");
      pos = end;
    }
  }
  int offset = utcOffsetMinutes.value_or(0);
  if (pos < text.size()) offset = parseUtcOffset(text.substr(pos));
  if (month < 1 || month > 12 || day < 1 || day > 31 || hour > 24 || minute > 59) {
    badTime(text, "field out of range");
  }
  ln_date date{year, month, day, hour, minute, second};
  return ln_get_julian_day(&date) - offset / 1440.0;
}

double sunDeclination(double julianDayUT) { return apparentEquatorial(julianDayUT).dec; }

SunPosition sunPosition(double julianDayUT, double longitude, double latitude,
                        const Atmosphere& atmosphere) {
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
