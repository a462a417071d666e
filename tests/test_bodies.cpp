// Right answers on the Earth and other bodies: longitudes at any turn, a light direction that
// holds at a pole (or is refused there), the Sun over a sub-solar point equal to Mars24's at an
// instant, points off a terrain said to be off it, and advice that names the body's own CRS.
// Expected values come from the rasters' own pixels, Mars24's published worked example and
// the vectors' definitions, not from qota's other answers.
#include <gtest/gtest.h>

#include <cmath>
#include <regex>
#include <sstream>

#include "qota_tools.hpp"
#include "raster_files.hpp"

namespace {

using qota::test::RasterSpec;
using qota::test::scratchPath;

struct ToolRun {
  int code;
  std::string out, err;
};

ToolRun sample(const qota::tools::SampleOptions& o, const std::string& input) {
  std::istringstream in(input);
  std::ostringstream out, err;
  const int code = qota::tools::sample(o, in, out, err);
  return {code, out.str(), err.str()};
}

ToolRun shadow(const qota::tools::ShadowOptions& o) {
  std::ostringstream out, err;
  const int code = qota::tools::shadow(o, out, err);
  return {code, out.str(), err.str()};
}

// A lon/lat grid of 1-degree pixels from west (its first pixel's west edge), width x height, with
// the height at a pixel centre f(lon, lat) = 1000 + lon + 10 lat (so every answer is known).
std::string lonLatGrid(const std::string& name, double west, int width, double north, int height,
                       const std::string& crs) {
  RasterSpec s;
  s.width = width, s.height = height;
  s.geotransform = {west, 1, 0, north, 0, -1};
  s.crs = crs;
  s.bands = {{}};
  for (int r = 0; r < height; ++r) {
    for (int c = 0; c < width; ++c) s.bands[0].push_back(1000 + (west + c + 0.5) + 10 * (north - r - 0.5));
  }
  const std::string path = scratchPath(name).string();
  qota::test::writeRaster(path, s);
  return path;
}

TEST(Bodies, ALongitudeNamesAMeridianAtAnyTurn) {
  // MOLA's convention, 0 to 360 east, asked at -9.5 (= 350.5): the pixel centre's own height.
  const std::string mars360 = lonLatGrid("lon360.tif", 0, 360, 60, 120, "+proj=longlat +R=3396190 +no_defs");
  // A tile across the antimeridian (170 to 190 east), asked at -179.5 (= 180.5).
  const std::string across = lonLatGrid("lon_across.tif", 170, 20, 20, 40, "EPSG:4326");
  for (const std::string mapping : {"cartesian", "geodetic", "spherical"}) {
    qota::tools::SampleOptions o;
    o.mapping = mapping;
    if (mapping == "geodetic") o.heightRef = "ellipsoid";
    o.source = mars360;
    const double want = 1000 + 350.5 + 10 * 10.5;  // (the spherical mapping answers the radius)
    ToolRun run = sample(o, "350.5 10.5\n-9.5 10.5\n710.5 10.5\n");
    ASSERT_EQ(run.code, 0) << mapping << ": " << run.err;
    std::istringstream lines(run.out);
    double a = 0, b = 0, c = 0;
    lines >> a >> b >> c;
    EXPECT_EQ(a, b) << mapping;
    EXPECT_EQ(a, c) << mapping;
    if (mapping != "spherical") {
      EXPECT_NEAR(a, want, 1e-6) << mapping;
    }
    o.source = across;
    run = sample(o, "180.5 10.5\n-179.5 10.5\n");
    ASSERT_EQ(run.code, 0) << mapping << ": " << run.err;
    std::istringstream more(run.out);
    more >> a >> b;
    EXPECT_EQ(a, b) << mapping;
    if (mapping != "spherical") {
      EXPECT_NEAR(a, 1000 + 180.5 + 105, 1e-6) << mapping;
    }
  }
}

TEST(Bodies, PointsOffTheTerrainAreSaidOffItInEveryMapping) {
  // A regional raster as a planet: a point far from it is off the raster (none, exit 1, a
  // message); before, "none" with exit 0 and nothing said.
  qota::tools::SampleOptions o;
  o.source = lonLatGrid("regional.tif", -122, 20, 47, 20, "EPSG:4326");
  o.mapping = "spherical";
  ToolRun run = sample(o, "0 0\n");
  EXPECT_EQ(run.code, 1);
  EXPECT_EQ(run.out, "none\n");
  EXPECT_NE(run.err.find("is off the raster"), std::string::npos) << run.err;
  // A city mesh given longitude/latitude: off its footprint.
  o.source = QOTA_DATA_DIR "/testarea.obj";
  o.mapping = "";
  run = sample(o, "-121.76 46.85\n");
  EXPECT_EQ(run.code, 1);
  EXPECT_EQ(run.out, "none\n");
  EXPECT_NE(run.err.find("is off the terrain"), std::string::npos) << run.err;
}

// A polar stereographic DEM centred on the South Pole (EPSG:3031), 40 x 40 pixels of 100 m.
std::string polarDem() {
  RasterSpec s;
  s.width = s.height = 40;
  s.geotransform = {-2000, 100, 0, 2000, 0, -100};
  s.crs = "EPSG:3031";
  s.bands = {{}};
  for (int r = 0; r < 40; ++r) {
    for (int c = 0; c < 40; ++c) s.bands[0].push_back(2800 + 60 * std::sin(c * 0.5) * std::cos(r * 0.4));
  }
  const std::string path = scratchPath("south_pole.tif").string();
  qota::test::writeRaster(path, s);
  return path;
}

std::vector<double> maskOf(const std::string& path) { return qota::test::readRaster(path).values; }

TEST(Bodies, AtAPoleTheLightIsTheBodysOwn) {
  const std::string dem = polarDem();
  qota::tools::ShadowOptions o;
  o.source = dem;
  o.output = scratchPath("pole_mask.tif").string();
  o.quiet = true;
  // -az/-alt (and --sun-vector) are east-north-up at the centre: undefined at the pole, refused.
  o.azimuth = 90, o.altitude = 1.5;
  ToolRun run = shadow(o);
  EXPECT_EQ(run.code, 2);
  EXPECT_NE(run.err.find("of a pole, where east and north are undefined"), std::string::npos) << run.err;
  EXPECT_NE(run.err.find("--sun-vector-body"), std::string::npos) << run.err;
  o.azimuth.reset(), o.altitude.reset();
  o.sunVector = Eigen::Vector3d(1, 0, 0.03);
  EXPECT_EQ(shadow(o).code, 2);
  o.sunVector.reset();
  // The Sun in the body's frame: from the +x axis (over longitude 0), 1.5 degrees above the
  // equator's plane; the same light as the sub-solar point (0, 1.5).
  const double e = 1.5 * M_PI / 180;
  o.sunVectorBody = Eigen::Vector3d(std::cos(e), 0, std::sin(e));
  run = shadow(o);
  ASSERT_EQ(run.code, 0) << run.err;
  const std::vector<double> byVector = maskOf(o.output);
  o.sunVectorBody.reset();
  o.subsolar = std::array<double, 2>{0, 1.5};
  run = shadow(o);
  ASSERT_EQ(run.code, 0) << run.err;
  EXPECT_EQ(maskOf(o.output), byVector);
  // At the South Pole a Sun 1.5 degrees north of the equator is below every horizon: all dark
  // but for the terrain's height (none here reaches the tangent cone): every cell in shadow.
  std::size_t lit = 0;
  for (double v : byVector) lit += v == 255;
  EXPECT_EQ(lit, 0u);
  // -az/-alt at a place away from the pole (--at) are taken there.
  o.subsolar.reset();
  o.azimuth = 0, o.altitude = 10, o.at = std::array<double, 2>{0, -60};
  EXPECT_EQ(shadow(o).code, 0);
}

const char* kMarsWkt =
    R"wkt(GEOGCRS["Mars (2015) - Sphere / Ocentric",DATUM["Mars (2015) - Sphere",ELLIPSOID["Mars (2015) - Sphere",3396190,0,LENGTHUNIT["metre",1]]],PRIMEM["Reference Meridian",0,ANGLEUNIT["degree",0.0174532925199433]],CS[ellipsoidal,2],AXIS["geodetic latitude (Lat)",north,ORDER[1],ANGLEUNIT["degree",0.0174532925199433]],AXIS["geodetic longitude (Lon)",east,ORDER[2],ANGLEUNIT["degree",0.0174532925199433]]])wkt";

TEST(Bodies, TheSunOverMars24sSubsolarPointIsMars24sSun) {
  // Mars24's worked example A: on 2000-01-06 00:00 UTC the Sun is over 174.72703 W, 25.22838 S
  // (the published values). A rough DEM 70 degrees away, where that Sun is low: --time and
  // --subsolar give the same light and the same shadows.
  RasterSpec s;
  s.width = s.height = 60;
  s.geotransform = {-120.3, 0.01, 0, 20.3, 0, -0.01};
  s.crs = kMarsWkt;
  s.bands = {{}};
  for (int r = 0; r < 60; ++r) {
    for (int c = 0; c < 60; ++c) s.bands[0].push_back(-2000 + 900 * std::sin(c * 0.31) * std::cos(r * 0.23));
  }
  const std::string dem = scratchPath("mars_rough.tif").string();
  qota::test::writeRaster(dem, s);
  qota::tools::ShadowOptions o;
  o.source = dem;
  o.output = scratchPath("mars_time.tif").string();
  o.quiet = true;
  o.time = "2000-01-06T00:00:00Z";
  ToolRun byTime = shadow(o);
  ASSERT_EQ(byTime.code, 0) << byTime.err;
  const std::vector<double> a = maskOf(o.output);
  o.time.clear();
  o.subsolar = std::array<double, 2>{-174.72703, -25.22838};
  ToolRun bySubsolar = shadow(o);
  ASSERT_EQ(bySubsolar.code, 0) << bySubsolar.err;
  const std::vector<double> b = maskOf(o.output);
  std::size_t differ = 0, dark = 0;
  for (std::size_t i = 0; i < a.size(); ++i) differ += a[i] != b[i], dark += a[i] == 0;
  EXPECT_GT(dark, a.size() / 50);      // a low Sun: shadows
  EXPECT_LE(differ * 2000, a.size());  // (the published decimals: 1e-5 degree)
}

TEST(Bodies, ReprojectionAdviceNamesTheBodysOwnCrs) {
  // A projected Mars DEM (equirectangular on Mars's sphere) in the geodetic mapping: the advice
  // names Mars's longitude/latitude, not the Earth's EPSG:4326.
  RasterSpec s;
  s.width = s.height = 10;
  s.geotransform = {0, 1000, 0, 0, 0, -1000};
  s.crs = "+proj=eqc +R=3396190 +units=m +no_defs";
  s.bands = {std::vector<double>(100, -1000.0)};
  const std::string dem = scratchPath("mars_eqc.tif").string();
  qota::test::writeRaster(dem, s);
  qota::tools::SampleOptions o;
  o.source = dem;
  o.mapping = "geodetic";
  const ToolRun run = sample(o, "0 0\n");
  EXPECT_EQ(run.code, 2);
  EXPECT_NE(run.err.find("+R=3396190"), std::string::npos) << run.err;
  EXPECT_EQ(run.err.find("EPSG:4326"), std::string::npos) << run.err;
}

}  // namespace
