// Solar position against published reference values.
#include <gtest/gtest.h>

#include "qota/error.hpp"
#include "qota/sun.hpp"

namespace {

TEST(Sun, NrelSpaWorkedExample) {
  // Reda & Andreas, "Solar Position Algorithm for Solar Radiation Applications", NREL/TP-560-34302
  // (2004), table A5.1: 2003-10-17 12:30:30 local (UTC-7), 39.742476 N, 105.1786 W, 820 mbar,
  // 11 C: topocentric zenith 50.11162 deg, azimuth 194.34024 deg (eastward from north).
  const double jd = qota::julianDayFromIso8601("2003-10-17T12:30:30-07:00");
  const qota::SunPosition s = qota::sunPosition(jd, -105.1786, 39.742476, {820, 11});
  EXPECT_NEAR(90 - s.altitude, 50.11162, 0.01);
  EXPECT_NEAR(s.azimuth, 194.34024, 0.01);
}

TEST(Sun, EquinoxesAndSolsticesOf2024) {
  // Published instants (UT, to the minute; e.g. USNO / timeanddate): the sun crosses the
  // equator at the equinoxes and reaches the true obliquity (23.4386 deg in 2024) at the
  // solstices. The sun's declination changes by at most 0.0003 deg in a minute.
  struct Ref {
    const char* when;
    double declination;
  };
  for (const Ref& r : {Ref{"2024-03-20T03:06Z", 0.0}, Ref{"2024-06-20T20:51Z", 23.4386},
                       Ref{"2024-09-22T12:44Z", 0.0}, Ref{"2024-12-21T09:21Z", -23.4386}}) {
    EXPECT_NEAR(qota::sunDeclination(qota::julianDayFromIso8601(r.when)), r.declination, 0.01) << r.when;
  }
}

TEST(Sun, NoonAltitudeAtTheEquinox) {
  // At the equator at the March 2024 equinox the sun culminates near the zenith; at 45 N it
  // culminates at 45 deg (plus about 0.02 deg of refraction), due south.
  const double jd = qota::julianDayFromIso8601("2024-03-20T12:07Z");  // near solar noon at 0 E
  const auto equator = qota::sunPosition(jd, 0, 0), north = qota::sunPosition(jd, 0, 45);
  EXPECT_GT(equator.altitude, 89.5);
  EXPECT_NEAR(north.altitude, 45.0, 0.2);
  EXPECT_NEAR(north.azimuth, 180.0, 1.0);
}

TEST(Sun, TimeParsing) {
  const double a = qota::julianDayFromIso8601("2024-06-21T12:00:00Z");
  EXPECT_DOUBLE_EQ(a, 2460483.0);
  EXPECT_DOUBLE_EQ(qota::julianDayFromIso8601("2024-06-21T14:00+02:00"), a);
  EXPECT_DOUBLE_EQ(qota::julianDayFromIso8601("2024-06-21 14:00", 120), a);
  EXPECT_DOUBLE_EQ(qota::julianDayFromIso8601("2024-06-21T12:00:00.000"), a);
  EXPECT_EQ(qota::parseUtcOffset("-05:30"), -330);
  EXPECT_THROW(qota::julianDayFromIso8601("21/06/2024"), qota::Error);
  EXPECT_THROW(qota::julianDayFromIso8601("2024-13-01T00:00"), qota::Error);
  EXPECT_THROW(qota::julianDayFromIso8601("2024-06-21T12"), qota::Error);
  EXPECT_THROW(qota::parseUtcOffset("+2h"), qota::Error);
}

}  // namespace
