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

// The mapping reached from the tool: a DEM placed on its ellipsoid and seen east-north-up.
#include <proj.h>

#include <sstream>

#include "qota_tools.hpp"
#include "raster_files.hpp"

namespace {

TEST(EnuTool, PixelCentresInTheFrameAreLocalCartesians) {
  // qota sample --mapping enu on a crop round Rainier's summit: at a pixel centre's (east, north)
  // in the frame, the answer is the centre's up, computed independently: its height over EGM96
  // plus PROJ's undulation there, to ECEF by GeographicLib, into the frame by LocalCartesian.
  const qota::test::RasterValues rainier = qota::test::readRaster(QOTA_DATA_DIR "/mt_rainier_90m.tif");
  qota::test::RasterSpec s;
  s.width = s.height = 200;
  s.geotransform = rainier.geotransform;
  s.geotransform[0] += 200 * rainier.geotransform[1];
  s.geotransform[3] += 100 * rainier.geotransform[5];
  s.crs = "EPSG:4326";
  s.nodata = -32768;
  s.bands = {{}};
  for (int r = 100; r < 300; ++r) {
    for (int c = 200; c < 400; ++c) s.bands[0].push_back(rainier.at(c, r));
  }
  const std::string path = qota::test::scratchPath("enu_summit.tif").string();
  qota::test::writeRaster(path, s);
  PJ_CONTEXT* ctx = proj_context_create();
  PJ* raw = proj_create_crs_to_crs(ctx, "EPSG:4326+5773", "EPSG:4979", nullptr);
  PJ* egm96 = proj_normalize_for_visualization(ctx, raw);
  const double lat0 = 46.85, lon0 = -121.76, h0 = 1000;
  const GeographicLib::LocalCartesian frame(lat0, lon0, h0, GeographicLib::Geocentric::WGS84());
  std::string input;
  std::vector<double> want;
  for (int k = 0; k < 60; ++k) {
    const int c = 20 + (k * 37) % 160, r = 20 + (k * 53) % 160;
    const double lon = s.geotransform[0] + (c + 0.5) * s.geotransform[1],
                 lat = s.geotransform[3] + (r + 0.5) * s.geotransform[5];
    const double h = s.bands[0][static_cast<std::size_t>(r) * 200 + c];
    if (h == -32768) continue;
    const double n = proj_trans(egm96, PJ_FWD, proj_coord(lon, lat, 0, 0)).xyz.z;
    double e = 0, no = 0, u = 0;
    frame.Forward(lat, lon, h + n, e, no, u);
    std::ostringstream line;
    line.precision(17);
    line << e << ' ' << no << '\n';
    input += line.str();
    want.push_back(u);
  }
  proj_destroy(egm96);
  proj_destroy(raw);
  proj_context_destroy(ctx);
  qota::tools::SampleOptions o;
  o.source = path;
  o.mapping = "enu";
  o.origin = std::array<double, 3>{lat0, lon0, h0};
  std::istringstream in(input);
  std::ostringstream out, err;
  ASSERT_EQ(qota::tools::sample(o, in, out, err), 0) << err.str();
  std::istringstream answers(out.str());
  for (const double u : want) {
    std::string text;
    ASSERT_TRUE(std::getline(answers, text));
    if (text == "none") continue;  // (every triangle round the centre touches a void)
    EXPECT_NEAR(std::stod(text), u, 1e-3);
  }
  // Off the terrain in the frame: far east of it.
  std::istringstream far("90000 0\n");
  std::ostringstream none, says;
  EXPECT_EQ(qota::tools::sample(o, far, none, says), 1);
  EXPECT_EQ(none.str(), "none\n");
}

}  // namespace
