// Solar position against published reference values; instants as users type them.
#include <gtest/gtest.h>

#include "qota/error.hpp"
#include "qota/instant.hpp"
#include "qota/sun.hpp"
#include "qota/sunlight.hpp"

namespace {

double jd(const char* text, const char* zone = "") { return qota::parseInstant(text, zone).julianDayUT; }

TEST(Sun, NrelSpaWorkedExample) {
  // Reda & Andreas, "Solar Position Algorithm for Solar Radiation Applications", NREL/TP-560-34302
  // (2004), table A5.1: 2003-10-17 12:30:30 local (UTC-7), 39.742476 N, 105.1786 W, 820 mbar,
  // 11 C: topocentric zenith 50.11162 deg, azimuth 194.34024 deg (eastward from north).
  const qota::SunPosition s = qota::sunPosition(jd("2003-10-17T12:30:30-07:00"), -105.1786, 39.742476, {820, 11});
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
  for (const Ref& r : {Ref{"2024-03-20T03:06Z", 0.0}, Ref{"2024-06-20T20:51Z", 23.4386}, Ref{"2024-09-22T12:44Z", 0.0},
                       Ref{"2024-12-21T09:21Z", -23.4386}}) {
    EXPECT_NEAR(qota::sunDeclination(jd(r.when)), r.declination, 0.01) << r.when;
  }
}

TEST(Sun, NoonAltitudeAtTheEquinox) {
  // At the equator at the March 2024 equinox the sun culminates near the zenith; at 45 N it
  // culminates at 45 deg (plus about 0.02 deg of refraction), due south.
  const double t = jd("2024-03-20T12:07Z");  // near solar noon at 0 E
  const auto equator = qota::sunPosition(t, 0, 0), north = qota::sunPosition(t, 0, 45);
  EXPECT_GT(equator.altitude, 89.5);
  EXPECT_NEAR(north.altitude, 45.0, 0.2);
  EXPECT_NEAR(north.azimuth, 180.0, 1.0);
}

TEST(Instant, OffsetsAndZones) {
  // 2024-06-21T12:00Z is Julian day 2460483.0 (JD 2451545.0 is 2000-01-01T12:00 TT; 8937 days on).
  const double a = jd("2024-06-21T12:00:00Z");
  EXPECT_DOUBLE_EQ(a, 2460483.0);
  EXPECT_DOUBLE_EQ(jd("2024-06-21T14:00+02:00"), a);
  EXPECT_DOUBLE_EQ(jd("2024-06-21T14:00+0200"), a);
  EXPECT_DOUBLE_EQ(jd("2024-06-21T14:00+02"), a);
  EXPECT_DOUBLE_EQ(jd("2024-06-21 14:00", "+02:00"), a);
  EXPECT_DOUBLE_EQ(jd("2024-06-21T12:00:00.000Z"), a);
  EXPECT_DOUBLE_EQ(jd("2024-06-21T12:00", "UTC"), a);
  // IANA zones from the system's tz database: Pacific Daylight Time in June, Standard in January.
  EXPECT_DOUBLE_EQ(jd("2024-06-21T05:00", "America/Los_Angeles"), a);
  EXPECT_DOUBLE_EQ(jd("2024-01-10T04:00", "America/Los_Angeles"), jd("2024-01-10T12:00Z"));
  EXPECT_DOUBLE_EQ(jd("2024-06-21T21:00", "Asia/Tokyo"), a);
  EXPECT_EQ(qota::parseInstant("2024-06-21T05:00", "America/Los_Angeles").utc, "2024-06-21T12:00:00Z");
  EXPECT_EQ(qota::parseInstant("2024-06-21T12:00:00.25Z").utc, "2024-06-21T12:00:00.25Z");
  EXPECT_EQ(qota::utcText(2460483.0), "2024-06-21T12:00:00Z");
}

TEST(Instant, InvalidTextIsAnErrorNamingIt) {
  const auto rejects = [](const char* text, const char* zone, const char* fragment) {
    try {
      qota::parseInstant(text, zone);
      ADD_FAILURE() << text << " was accepted";
    } catch (const qota::Error& e) {
      EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << text << ": " << e.what();
    }
  };
  rejects("2024-02-30T12:00Z", "", "no such date");
  rejects("2023-02-29T12:00Z", "", "no such date");
  rejects("2024-13-01T00:00Z", "", "no such date");
  rejects("2024-06-21T24:00Z", "", "hour 24");
  rejects("2024-06-21T12:60Z", "", "minute 60");
  rejects("2024-06-21T12:00:60Z", "", "second 60");
  rejects("21/06/2024", "", "not a date");
  rejects("2024-06-21T12", "", "not a time of day");
  rejects("2024-06-21T12:00+2h", "", "not a UTC offset");
  rejects("2024-06-21T12:00", "", "no UTC offset");
  rejects("2024-06-21T12:00Z", "+02:00", "give only one");
  rejects("2024-06-21T12:00", "Europe/Atlantis", "Europe/Atlantis");
  // Daylight saving in Los Angeles: 02:30 on 2024-03-10 never happens, 01:30 on 2024-11-03 twice.
  rejects("2024-03-10T02:30", "America/Los_Angeles", "does not exist");
  rejects("2024-11-03T01:30", "America/Los_Angeles", "happens twice");
}

TEST(Instant, LocalSpanOnDaylightSavingDays) {
  // Midnight to midnight in Los Angeles lasts 23 h on 2024-03-10 and 25 h on 2024-11-03.
  const auto spring = qota::localSpan("2024-03-10", "America/Los_Angeles", 0, 24);
  EXPECT_NEAR((spring.end.julianDayUT - spring.start.julianDayUT) * 24, 23.0, 1e-7);  // a JD's ulp: 40 us
  const auto fall = qota::localSpan("2024-11-03", "America/Los_Angeles", 0, 24);
  EXPECT_NEAR((fall.end.julianDayUT - fall.start.julianDayUT) * 24, 25.0, 1e-7);
  EXPECT_EQ(fall.start.utc, "2024-11-03T07:00:00Z");
  // An offset written in the time applies to its whole day.
  const auto fixed = qota::localSpan("2024-06-21T10:00-07:00", "", 4, 22);
  EXPECT_EQ(fixed.start.utc, "2024-06-21T11:00:00Z");
  EXPECT_EQ(fixed.end.utc, "2024-06-22T05:00:00Z");
}

TEST(Mars24, LeapSeconds) {
  // TT - UTC: 32.184 s plus TAI - UTC (IERS Bulletin C): 32 s in 2000, 37 s since 2017.
  EXPECT_DOUBLE_EQ(qota::ttMinusUtc(jd("2000-01-06T00:00Z")), 64.184);
  EXPECT_DOUBLE_EQ(qota::ttMinusUtc(jd("2016-12-31T23:59Z")), 68.184);
  EXPECT_DOUBLE_EQ(qota::ttMinusUtc(jd("2024-06-21T12:00Z")), 69.184);
  EXPECT_THROW(qota::ttMinusUtc(jd("1969-07-20T20:17Z")), qota::Error);
}

// The two worked examples of NASA GISS's "Mars24 Algorithm and Worked Examples" (the revision of
// 2015, as every Mars24 implementation that checks against them quotes it), to their printed
// decimals (the declination and what follows from it: to the closed form's accuracy).
TEST(Mars24, WorkedExampleA) {
  // 2000-01-06 00:00:00 UTC (millis 947116800000), at 0 W, 0 N.
  const double t = jd("2000-01-06T00:00:00Z");
  EXPECT_DOUBLE_EQ(t, 2451549.5);
  const qota::Mars24 m = qota::mars24(t);
  EXPECT_NEAR(m.deltaJ2000, 4.50074, 1e-5);
  EXPECT_NEAR(m.meanAnomaly, 21.74548, 1e-5);
  EXPECT_NEAR(m.fmsAngle, 272.74486, 1e-5);
  EXPECT_NEAR(m.perturbers, 0.00142, 1e-5);
  EXPECT_NEAR(m.equationOfCenter, 4.44191, 1e-5);
  EXPECT_NEAR(m.ls, 277.18677, 1e-5);
  EXPECT_NEAR(m.equationOfTime, -5.18764, 1e-5);
  EXPECT_NEAR(m.meanSolarTime, 23.99431, 1e-5);
  EXPECT_NEAR(m.localTrueSolarTime(0), 23.64847, 1e-5);
  EXPECT_NEAR(m.subsolarWest, 174.72703, 1e-5);
  // D-1's closed form (asin(0.42565 sin Ls) + 0.25 sin Ls) gives the published declinations to
  // 1e-4 here and 5e-3 in example B: they came from a fuller solution, and the closed form's
  // stated accuracy is 0.01 degree.
  EXPECT_NEAR(m.declination, -25.22838, 1e-4);
  EXPECT_NEAR(m.distance, 1.39358, 1e-5);
  const qota::SunPosition s = qota::marsSunPosition(t, 0, 0);
  EXPECT_NEAR(90 - s.altitude, 154.26182, 1e-4);  // D-5 zenith
  EXPECT_NEAR(s.azimuth, 191.03687, 1e-4);        // D-6
}

TEST(Mars24, WorkedExampleB) {
  // The Mars Exploration Rover Spirit's landing: 2004-01-03 13:46:31 UTC (millis 1073137591000),
  // at 184.702 W, 14.640 S.
  const double t = jd("2004-01-03T13:46:31Z");
  EXPECT_NEAR(t, 2453008.07397, 1e-5);
  const qota::Mars24 m = qota::mars24(t);
  EXPECT_NEAR(m.deltaJ2000, 1463.07471, 1e-5);
  EXPECT_NEAR(m.meanAnomaly, 66.06851, 1e-5);
  EXPECT_NEAR(m.fmsAngle, 317.09363, 1e-5);
  EXPECT_NEAR(m.perturbers, 0.01614, 1e-5);
  EXPECT_NEAR(m.equationOfCenter, 10.22959, 1e-5);
  EXPECT_NEAR(m.ls, 327.32322, 1e-5);
  EXPECT_NEAR(m.equationOfTime, -12.77557, 1e-5);
  EXPECT_NEAR(m.meanSolarTime, 13.16542, 1e-5);
  EXPECT_NEAR(m.localTrueSolarTime(184.702), 0.00025, 1e-5);
  EXPECT_NEAR(m.subsolarWest, 4.70575, 1e-5);
  EXPECT_NEAR(m.distance, 1.47767, 1e-5);
  const double east = 360 - 184.702;
  const qota::SunPosition s = qota::marsSunPosition(t, east, -14.640);
  EXPECT_NEAR(90 - s.altitude, 151.93895, 0.01);
  EXPECT_NEAR(s.azimuth, 179.99225, 0.01);
  EXPECT_NEAR(m.declination, -13.42105, 0.01);
}

TEST(Mars24, SunOverheadAtTheSubsolarPoint) {
  const double t = jd("2024-06-21T12:00Z");
  const qota::Mars24 m = qota::mars24(t);
  const qota::SunPosition s = qota::marsSunPosition(t, -m.subsolarWest, m.declination);
  EXPECT_NEAR(s.altitude, 90.0, 1e-6);
  const qota::SunPosition far = qota::marsSunPosition(t, 180 - m.subsolarWest, -m.declination);
  EXPECT_NEAR(far.altitude, -90.0, 1e-6);
}

}  // namespace

namespace {

TEST(Sunlight, AStepAsLongAsTheSpanIsOneStep) {
  // Half an hour from 20:30 local (Julian days carry rounding of some 1e-8 h): one step of 0.5 h,
  // as asked; a quarter of an hour gives two; a step longer than the span is refused.
  const double start = 2460483.647916667, end = start + 0.5 / 24;
  const std::vector<qota::SunlightStep> one = qota::sunlightSteps(start, end, 0.5);
  ASSERT_EQ(one.size(), 1u);
  EXPECT_NEAR(one[0].hours, 0.5, 1e-6);
  EXPECT_EQ(qota::sunlightSteps(start, end, 0.25).size(), 2u);
  EXPECT_EQ(qota::sunlightSteps(start, start + 18.0 / 24, 0.25).size(), 72u);
  EXPECT_THROW(qota::sunlightSteps(start, end, 0.51), qota::Error);
}

}  // namespace
