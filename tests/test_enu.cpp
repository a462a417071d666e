// The east-north-up mapping against GeographicLib::LocalCartesian (an independent
// implementation of the same frame), its round trips, and its refusals.
#include <gtest/gtest.h>

#include <GeographicLib/Geocentric.hpp>
#include <GeographicLib/LocalCartesian.hpp>
#include <algorithm>
#include <random>

#include "qota/any_mapping.hpp"
#include "qota/error.hpp"

namespace {

using namespace qota;

TEST(EnuMapping, MatchesLocalCartesian) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> lat(-90, 90), lon(-540, 540), h(-1e4, 1e4), d(-0.5, 0.5);
  const GeographicLib::Geocentric& earth = GeographicLib::Geocentric::WGS84();
  for (int i = 0; i < 200; ++i) {
    double lat0 = lat(rng), lon0 = lon(rng), h0 = h(rng);
    if (i == 0) lat0 = 90;
    if (i == 1) lat0 = -90, lon0 = 180;
    const EnuMapping enu(lat0, lon0, h0);
    const GeographicLib::LocalCartesian reference(lat0, lon0, h0, earth);
    for (int k = 0; k < 20; ++k) {
      // Points within about 50 km of the origin, as an ENU frame is used.
      const double plat = std::clamp(lat0 + d(rng), -90.0, 90.0), plon = lon0 + d(rng), ph = h(rng);
      double x, y, z, e, n, u;
      earth.Forward(plat, plon, ph, x, y, z);
      reference.Forward(plat, plon, ph, e, n, u);
      const Eigen::Vector3d m = enu.toMapped({x, y, z});
      ASSERT_NEAR(m.x(), e, 1e-6) << lat0 << " " << lon0;
      ASSERT_NEAR(m.y(), n, 1e-6) << lat0 << " " << lon0;
      ASSERT_NEAR(m.z(), u, 1e-6) << lat0 << " " << lon0;
      ASSERT_LE((enu.toWorld(m) - Eigen::Vector3d(x, y, z)).norm(), 1e-6);
    }
    // The line of (u, v) is straight down the origin's up, through the point of h = 0.
    const MappedLine line = enu.line(123, -456);
    EXPECT_NEAR(enu.toMapped(line.origin + 789.0 * line.down).z(), -789.0, 1e-6);
    EXPECT_NEAR(line.down.norm(), 1.0, 1e-15);
  }
}

TEST(EnuMapping, ItsOwnEllipsoid) {
  // A sphere of radius 3396190 m (Mars): up is the radial direction, the origin at radius + h0.
  const EnuMapping mars(30, 60, 100, 3396190, 0);
  EXPECT_NEAR(mars.origin().norm(), 3396290, 1e-6);
  EXPECT_NEAR((mars.origin().normalized() - mars.up()).norm(), 0, 1e-15);
}

TEST(EnuMapping, DescribeReadsBackAndBadValuesAreErrors) {
  const EnuMapping enu(46.85, -121.76, 1500.5);
  const std::string text = describe(AnyMapping(enu));
  EXPECT_EQ(describe(parseMapping(text)), text);
  EXPECT_EQ(std::get<EnuMapping>(parseMapping(text)).frame().rotation, enu.frame().rotation);
  EXPECT_EQ(mappingName(parseMapping("enu lat=10")), std::string("enu"));
  EXPECT_NE(mappingNames().find("enu"), std::string::npos);
  for (const char* bad : {"enu lat=91", "enu lon=nan", "enu h=inf", "enu a=0", "enu f=1", "enu centre=1,2,3"}) {
    EXPECT_THROW(parseMapping(bad), Error) << bad;
  }
  EXPECT_THROW(EnuMapping(-90.5, 0), Error);
}

}  // namespace
