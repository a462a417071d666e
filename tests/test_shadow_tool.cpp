// qota shadow's answers against computations that do not use qota: an independent solar formula
// over whole-globe and continental DEMs, the same DEM in other vertical units, Mars24's published
// worked examples, and the refusals a user needs.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <map>
#include <regex>
#include <sstream>

#include "qota_tools.hpp"
#include "raster_files.hpp"
#include "text_output.hpp"

namespace {

using qota::test::RasterSpec;
using qota::test::RasterValues;
using qota::test::scratchPath;
using qota::tools::ShadowOptions;

constexpr double kDeg = M_PI / 180;

struct ShadowRun {
  int code;
  std::string out, err;
};

ShadowRun shadow(const ShadowOptions& o) {
  std::ostringstream out, err;
  const int code = qota::tools::shadow(o, out, err);
  return {code, out.str(), err.str()};
}

ShadowOptions options(const std::string& source, const std::string& output) {
  ShadowOptions o;
  o.source = source;
  o.output = scratchPath(output).string();
  o.quiet = true;
  return o;
}

// The sun's altitude (degrees) at a place and instant, by the U.S. Naval Observatory's
// "Approximate Solar Coordinates" (about 1 arcminute from 1950 to 2050): independent of the
// VSOP87 theory qota uses.
double usnoAltitude(double julianDayUT, double lon, double lat) {
  const double D = julianDayUT - 2451545.0;
  const double g = (357.529 + 0.98560028 * D) * kDeg;
  const double q = 280.459 + 0.98564736 * D;
  const double L = (q + 1.915 * std::sin(g) + 0.020 * std::sin(2 * g)) * kDeg;
  const double e = (23.439 - 0.00000036 * D) * kDeg;
  const double ra = std::atan2(std::cos(e) * std::sin(L), std::cos(L));
  const double dec = std::asin(std::sin(e) * std::sin(L));
  const double gmst = 18.697374558 + 24.06570982441908 * D;  // hours
  const double H = std::fmod(gmst, 24.0) * 15 * kDeg + lon * kDeg - ra;
  return std::asin(std::sin(lat * kDeg) * std::sin(dec) + std::cos(lat * kDeg) * std::cos(dec) * std::cos(H)) / kDeg;
}

// A crop of a raster written as its own GeoTIFF (columns c0 .. c1 - 1, rows r0 .. r1 - 1).
std::string crop(const RasterValues& r, const std::string& crs, int c0, int c1, int r0, int r1, const std::string& name,
                 std::optional<double> nodata = std::nullopt) {
  RasterSpec s;
  s.nodata = nodata;
  s.width = c1 - c0, s.height = r1 - r0;
  s.geotransform = r.geotransform;
  s.geotransform[0] += c0 * r.geotransform[1];
  s.geotransform[3] += r0 * r.geotransform[5];
  s.crs = crs;
  s.bands = {{}};
  for (int row = r0; row < r1; ++row) {
    for (int col = c0; col < c1; ++col) s.bands[0].push_back(r.at(col, row));
  }
  const auto path = scratchPath(name);
  qota::test::writeRaster(path, s);
  return path.string();
}

// Checks a shadow mask of a lon/lat grid against the independent solar formula: dark where the
// sun is farther below the horizon than the dip of the horizon from the highest terrain (plus
// half a degree for refraction and the formula), lit where it is higher than 20 degrees (no
// slope of these pixels can hide it); with polarDay (a June solstice), lit everywhere north of
// 80 N, where the sun stays more than 13 degrees up all day.
void checkAgainstSolarFormula(const std::string& mask, double julianDayUT, double highest, const std::string& what,
                              bool polarDay) {
  const RasterValues m = qota::test::readRaster(mask);
  const double dip = std::acos(6371000.0 / (6371000.0 + highest)) / kDeg + 0.5;
  std::size_t dark = 0, lit = 0, night = 0, day = 0, polar = 0, pixels = 0;
  for (int r = 0; r < m.height; ++r) {
    for (int c = 0; c < m.width; ++c) {
      const double lon = m.geotransform[0] + (c + 0.5) * m.geotransform[1];
      const double lat = m.geotransform[3] + (r + 0.5) * m.geotransform[5];
      const double alt = usnoAltitude(julianDayUT, lon, lat), v = m.at(c, r);
      ++pixels;
      lit += v == 255, dark += v == 0;
      if (alt < -dip) {
        ++night;
        EXPECT_EQ(v, 0) << what << ": lit at " << lon << ", " << lat << " with the sun " << -alt
                        << " deg below the horizon";
      }
      if (alt > 20) {
        ++day;
        EXPECT_EQ(v, 255) << what << ": dark at " << lon << ", " << lat << " with the sun " << alt << " deg up";
      }
      if (polarDay && lat > 80) {
        ++polar;
        EXPECT_EQ(v, 255) << what << ": polar day dark at " << lon << ", " << lat;
      }
    }
  }
  EXPECT_EQ(lit + dark, pixels) << what;
  EXPECT_GT(night, pixels / 20) << what;
  EXPECT_GT(day, pixels / 20) << what;
  if (polarDay && m.geotransform[3] > 85) {
    EXPECT_GT(polar, 0u) << what;
  }
}

TEST(ShadowTool, WholeGlobeAtOneInstant) {
  // ETOPO at 20 arc-minutes at 2024-06-21T12:00Z: day, night and polar day where the sun is.
  const std::string etopo = QOTA_DATA_DIR "/etopo20.tif";
  ShadowOptions o = options(etopo, "globe.tif");
  o.time = "2024-06-21T12:00Z";
  const ShadowRun run = shadow(o);
  ASSERT_EQ(run.code, 0) << run.err;
  const RasterValues e = qota::test::readRaster(etopo);
  const double highest = *std::max_element(e.values.begin(), e.values.end());
  checkAgainstSolarFormula(o.output, 2460483.0, highest, "etopo20", true);
  // About half the globe is lit (a little more: the terminator is a great circle, and the
  // highest terrain sees past it).
  const RasterValues m = qota::test::readRaster(o.output);
  const double litShare = static_cast<double>(std::count(m.values.begin(), m.values.end(), 255.0)) / m.values.size();
  double expected = 0, total = 0;  // the share of pixels under a sun above the horizon
  for (int r = 0; r < m.height; ++r) {
    const double lat = m.geotransform[3] + (r + 0.5) * m.geotransform[5];
    for (int c = 0; c < m.width; ++c) {
      const double lon = m.geotransform[0] + (c + 0.5) * m.geotransform[1];
      total += 1;
      expected += usnoAltitude(2460483.0, lon, lat) > 0;
    }
  }
  EXPECT_NEAR(litShare, expected / total, 0.02);
}

TEST(ShadowTool, ContinentalCropsAndOtherInstants) {
  // Crops wider than 180 degrees of longitude and other instants: the same properties.
  const std::string etopo = QOTA_DATA_DIR "/etopo20.tif";
  const RasterValues e = qota::test::readRaster(etopo);
  const double highest = *std::max_element(e.values.begin(), e.values.end());
  // 150 W to 150 E, 80 S to 88 N; and 20 W to 170 E, 10 S to 75 N.
  const std::string wide = crop(e, "EPSG:4326", 90, 990, 6, 510, "wide.tif");
  const std::string eurasia = crop(e, "EPSG:4326", 480, 1050, 45, 300, "eurasia.tif");
  for (const auto& [source, when, jd] :
       {std::tuple{wide, "2024-06-21T12:00Z", 2460483.0}, std::tuple{wide, "2024-12-21T06:30Z", 2460665.7708333335},
        std::tuple{eurasia, "2024-03-20T06:00Z", 2460389.75}}) {
    ShadowOptions o = options(source, "crop.tif");
    o.time = when;
    const ShadowRun run = shadow(o);
    ASSERT_EQ(run.code, 0) << run.err;
    checkAgainstSolarFormula(o.output, jd, highest, source + " at " + when, jd == 2460483.0);
  }
}

TEST(ShadowTool, ProjectedContinentIsPutOnTheEllipsoid) {
  // The globe between 80 S and 80 N in Web Mercator: a projected DEM is placed on the ellipsoid
  // too, pixel by pixel, so the terminator falls where the sun sets.
  if (std::system("gdalwarp --version > /dev/null 2>&1") != 0) GTEST_SKIP() << "no gdalwarp";
  const auto merc = scratchPath("mercator.tif");
  std::filesystem::remove(merc);
  const std::string cmd =
      "gdalwarp -q -overwrite -t_srs EPSG:3857 -te -20037508 -15538711 20037508 15538711 -ts 720 558 " +
      std::string(QOTA_DATA_DIR "/etopo20.tif ") + merc.string();
  ASSERT_EQ(std::system(cmd.c_str()), 0);
  ShadowOptions o = options(merc.string(), "mercator_mask.tif");
  o.time = "2024-06-21T12:00Z";
  const ShadowRun run = shadow(o);
  ASSERT_EQ(run.code, 0) << run.err;
  const RasterValues m = qota::test::readRaster(o.output);
  std::size_t checked = 0;
  for (int r = 0; r < m.height; ++r) {
    for (int c = 0; c < m.width; ++c) {
      const double x = m.geotransform[0] + (c + 0.5) * m.geotransform[1];
      const double y = m.geotransform[3] + (r + 0.5) * m.geotransform[5];
      const double lon = x / 6378137.0 / kDeg, lat = (2 * std::atan(std::exp(y / 6378137.0)) - M_PI / 2) / kDeg;
      const double alt = usnoAltitude(2460483.0, lon, lat), v = m.at(c, r);
      if (v == 128) continue;
      if (alt < -3.5) {
        EXPECT_EQ(v, 0) << lon << ", " << lat;
      }
      if (alt > 20) {
        EXPECT_EQ(v, 255) << lon << ", " << lat;
      }
      ++checked;
    }
  }
  EXPECT_GT(checked, 300000u);
}

// A crop of the Rainier tile around the summit, with heights made exact multiples of a foot.
struct FeetDem {
  RasterValues r;
  std::vector<double> feet;  // whole numbers
};
FeetDem feetDem(double metresPerFoot) {
  const RasterValues full = qota::test::readRaster(QOTA_DATA_DIR "/mt_rainier_90m.tif");
  FeetDem d;
  d.r.width = d.r.height = 300;
  d.r.geotransform = full.geotransform;
  d.r.geotransform[0] += 200 * full.geotransform[1];
  d.r.geotransform[3] += 100 * full.geotransform[5];
  for (int row = 100; row < 400; ++row) {
    for (int col = 200; col < 500; ++col) {
      const double v = full.at(col, row);
      d.feet.push_back(v == -32768 ? -32768 : std::round(v / metresPerFoot));
    }
  }
  return d;
}

std::string writeHeights(const FeetDem& d, const std::string& name, const std::string& crs, double scale,
                         const std::string& unit) {
  RasterSpec s;
  s.width = s.height = 300;
  s.geotransform = d.r.geotransform;
  s.crs = crs;
  s.nodata = -32768;
  s.unitType = unit;
  s.bands = {{}};
  for (double f : d.feet) s.bands[0].push_back(f == -32768 ? f : f * scale);
  const auto path = scratchPath(name);
  qota::test::writeRaster(path, s);
  return path.string();
}

std::vector<double> maskOf(ShadowOptions o) {
  const ShadowRun run = shadow(o);
  EXPECT_EQ(run.code, 0) << run.err;
  return qota::test::readRaster(o.output).values;
}

TEST(ShadowTool, HeightsInFeetCastTheShadowsOfMetres) {
  // The same terrain in metres and in feet (band unit type, or a vertical CRS in US survey feet,
  // or no unit and -z): the same mask, pixel for pixel, at a low sun. Heights are whole feet, so
  // the metres are exactly the feet times the foot.
  for (const auto& [foot, unit, crs] :
       {std::tuple{0.3048, std::string("ft"), std::string("EPSG:4326")},
        std::tuple{0.3048, std::string("foot"), std::string("EPSG:4326")},
        std::tuple{1200.0 / 3937.0, std::string("US survey foot"), std::string("EPSG:4326")},
        std::tuple{1200.0 / 3937.0, std::string(""), std::string("EPSG:4326+6360")}}) {
    const FeetDem d = feetDem(foot);
    const std::string metres = writeHeights(d, "metres.tif", "EPSG:4326", foot, "m");
    const std::string feet = writeHeights(d, "feet.tif", crs, 1, unit);
    ShadowOptions a = options(metres, "mask_m.tif"), b = options(feet, "mask_ft.tif");
    a.azimuth = b.azimuth = 250;
    a.altitude = b.altitude = 8;
    a.heightRef = b.heightRef = "ellipsoid";  // (NAVD88's geoid is not one qota has)
    const auto ma = maskOf(a), mb = maskOf(b);
    ASSERT_EQ(ma.size(), mb.size());
    std::size_t differ = 0, dark = 0;
    for (std::size_t i = 0; i < ma.size(); ++i) differ += ma[i] != mb[i], dark += ma[i] == 0;
    EXPECT_EQ(differ, 0u) << unit << " " << crs;
    EXPECT_GT(dark, ma.size() / 20) << unit << " " << crs;
    // Sampling keeps the raster's own unit, as gdallocationinfo prints it: at a pixel centre,
    // the raster's value in feet.
    qota::tools::SampleOptions so;
    so.source = feet;
    const double x = d.r.geotransform[0] + 150.5 * d.r.geotransform[1],
                 y = d.r.geotransform[3] + 120.5 * d.r.geotransform[5];
    std::istringstream in(qota::tools::formatNumber(x) + " " + qota::tools::formatNumber(y) + "\n");
    std::ostringstream out, err;
    qota::tools::sample(so, in, out, err);
    EXPECT_EQ(std::stod(out.str()), d.feet[120 * 300 + 150]) << err.str();
  }
  // A raster that says nothing about its unit: -z converts it.
  const FeetDem d = feetDem(0.3048);
  const std::string metres = writeHeights(d, "metres.tif", "EPSG:4326", 0.3048, "");
  const std::string bare = writeHeights(d, "bare_feet.tif", "EPSG:4326", 1, "");
  ShadowOptions a = options(metres, "mask_m.tif"), b = options(bare, "mask_z.tif");
  a.azimuth = b.azimuth = 250;
  a.altitude = b.altitude = 8;
  b.zFactor = 0.3048;
  EXPECT_EQ(maskOf(a), maskOf(b));
  // -s (horizontal units per vertical unit) is -z's reciprocal on a metric grid; it does not
  // apply when the raster names its unit.
  ShadowOptions c = options(writeHeights(d, "utm.tif", "EPSG:32610", 1, ""), "mask_s.tif"), z = c;
  z.output = scratchPath("mask_zz.tif").string();
  c.scale = 4;
  z.zFactor = 0.25;
  c.altitude = z.altitude = 10;
  EXPECT_EQ(maskOf(c), maskOf(z));
  b.source = writeHeights(d, "feet.tif", "EPSG:4326", 1, "ft");
  b.zFactor = 1;
  b.scale = 3;
  const ShadowRun refused = shadow(b);
  EXPECT_EQ(refused.code, 2);
  EXPECT_NE(refused.err.find("-s/--scale"), std::string::npos) << refused.err;
}

// A small DEM on another body, centred at (lon, lat).
std::string bodyDem(const std::string& name, const std::string& wkt, double lon, double lat) {
  RasterSpec s;
  s.width = s.height = 20;
  s.geotransform = {lon - 0.1, 0.01, 0, lat + 0.1, 0, -0.01};
  s.crs = wkt;
  s.bands = {std::vector<double>(400, -1000.0)};
  for (int i = 0; i < 400; ++i) s.bands[0][i] += 37 * std::sin(i * 0.37);
  const auto path = scratchPath(name);
  qota::test::writeRaster(path, s);
  return path.string();
}

const char* kMarsWkt =
    R"wkt(GEOGCRS["Mars (2015) - Sphere / Ocentric",DATUM["Mars (2015) - Sphere",ELLIPSOID["Mars (2015) - Sphere",3396190,0,LENGTHUNIT["metre",1]]],PRIMEM["Reference Meridian",0,ANGLEUNIT["degree",0.0174532925199433]],CS[ellipsoidal,2],AXIS["geodetic latitude (Lat)",north,ORDER[1],ANGLEUNIT["degree",0.0174532925199433]],AXIS["geodetic longitude (Lon)",east,ORDER[2],ANGLEUNIT["degree",0.0174532925199433]]])wkt";
const char* kMoonWkt =
    R"wkt(GEOGCRS["Moon (2015) - Sphere / Ocentric",DATUM["Moon (2015) - Sphere",ELLIPSOID["Moon (2015) - Sphere",1737400,0,LENGTHUNIT["metre",1]]],PRIMEM["Reference Meridian",0,ANGLEUNIT["degree",0.0174532925199433]],CS[ellipsoidal,2],AXIS["geodetic latitude (Lat)",north,ORDER[1],ANGLEUNIT["degree",0.0174532925199433]],AXIS["geodetic longitude (Lon)",east,ORDER[2],ANGLEUNIT["degree",0.0174532925199433]]])wkt";

// The light line of a run: "azimuth A deg, altitude B deg".
std::pair<double, double> lightOf(const std::string& out) {
  std::smatch m;
  const std::regex re("azimuth ([-0-9.]+) deg, altitude ([-0-9.]+) deg");
  if (!std::regex_search(out, m, re)) return {NAN, NAN};
  return {std::stod(m[1]), std::stod(m[2])};
}

TEST(ShadowTool, MarsTakesTheSunFromMars24) {
  // Mars24's worked example B (the Spirit landing, 2004-01-03 13:46:31 UTC, at 184.702 W,
  // 14.640 S): the Sun 151.93895 degrees from the zenith, azimuth 179.99225; every pixel dark.
  ShadowOptions o = options(bodyDem("spirit.tif", kMarsWkt, 360 - 184.702, -14.640), "spirit_mask.tif");
  o.quiet = false;
  o.time = "2004-01-03T13:46:31Z";
  ShadowRun run = shadow(o);
  ASSERT_EQ(run.code, 0) << run.err;
  const auto [az, alt] = lightOf(run.out);
  EXPECT_NEAR(alt, 90 - 151.93895, 0.01) << run.out;
  EXPECT_NEAR(az, 179.99225, 0.01) << run.out;
  EXPECT_NE(run.out.find("on Mars"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find("lit: 0.00 %"), std::string::npos) << run.out;
  // Example A's subsolar point (2000-01-06 00:00 UTC: 174.72703 W, 25.22838 S): the Sun overhead,
  // every pixel lit (the DEM is gentle).
  o.source = bodyDem("subsolar.tif", kMarsWkt, 360 - 174.72703, -25.22838);
  o.time = "2000-01-06T00:00:00Z";
  run = shadow(o);
  ASSERT_EQ(run.code, 0) << run.err;
  EXPECT_GT(lightOf(run.out).second, 89.99) << run.out;
  EXPECT_NE(run.out.find("lit: 100.00 %"), std::string::npos) << run.out;
  // Any other body: refused, pointing to the other ways of giving the light.
  o.source = bodyDem("moon.tif", kMoonWkt, 10, 10);
  run = shadow(o);
  EXPECT_EQ(run.code, 2);
  EXPECT_NE(run.err.find("Moon"), std::string::npos) << run.err;
  EXPECT_NE(run.err.find("-az/-alt"), std::string::npos) << run.err;
  EXPECT_NE(run.err.find("--sun-vector"), std::string::npos) << run.err;
  o.time.clear();
  o.azimuth = 90;
  o.altitude = 20;
  EXPECT_EQ(shadow(o).code, 0);
}

TEST(ShadowTool, HoursCountTheDay) {
  // A flat DEM: every pixel is lit while the sun is up, so the hours of sunlight over the whole
  // local day are the day's length, from the independent formula (sunrise and sunset where the
  // sun's centre is 0.5 degree below the horizon: refraction), to within a step.
  RasterSpec s;
  s.width = s.height = 30;
  s.geotransform = {-121.8, 0.001, 0, 46.9, 0, -0.001};
  s.crs = "EPSG:4326";
  s.bands = {std::vector<double>(900, 500.0)};
  const auto path = scratchPath("flat.tif");
  qota::test::writeRaster(path, s);
  ShadowOptions o = options(path.string(), "flat_hours.tif");
  o.time = "2024-06-21";
  o.tz = "America/Los_Angeles";
  o.hours = std::array<double, 3>{0, 24, 0.1};
  ASSERT_EQ(shadow(o).code, 0);
  const RasterValues h = qota::test::readRaster(o.output);
  double day = 0;
  const double start = 2460482.5 + 7.0 / 24;  // local midnight, PDT = UTC - 7
  for (int k = 0; k < 24 * 600; ++k) day += usnoAltitude(start + (k + 0.5) / (24 * 600), -121.785, 46.885) > -0.5;
  day /= 600;
  for (double v : h.values) EXPECT_NEAR(v, day, 0.15);
  // Steps that mean nothing are refused.
  for (const auto& hours :
       {std::array<double, 3>{4, 22, 1e-12}, std::array<double, 3>{4, 22, 30}, std::array<double, 3>{22, 4, 1},
        std::array<double, 3>{0, 49, 1}, std::array<double, 3>{4, 22, NAN}}) {
    o.hours = hours;
    const ShadowRun run = shadow(o);
    EXPECT_EQ(run.code, 2) << hours[0] << " " << hours[1] << " " << hours[2];
    EXPECT_NE(run.err.find("--hours"), std::string::npos) << run.err;
  }
}

TEST(ShadowTool, RefusesWhatWouldLoseData) {
  const std::string helens = QOTA_DATA_DIR "/SainteHelens.dem";
  // Equal values could not be told apart.
  ShadowOptions o = options(helens, "values.tif");
  o.litValue = 0;
  ShadowRun run = shadow(o);
  EXPECT_EQ(run.code, 2);
  EXPECT_NE(run.err.find("must differ"), std::string::npos) << run.err;
  EXPECT_FALSE(std::filesystem::exists(o.output));
  // A VRT holds no pixels.
  o = options(helens, "mask.vrt");
  run = shadow(o);
  EXPECT_EQ(run.code, 2);
  EXPECT_NE(run.err.find("VRT"), std::string::npos) << run.err;
  EXPECT_FALSE(std::filesystem::exists(o.output));
  // The output must not be the input; the input stays as it was.
  const auto copy = scratchPath("input.tif");
  std::filesystem::copy_file(QOTA_DATA_DIR "/mt_rainier_90m.tif", copy,
                             std::filesystem::copy_options::overwrite_existing);
  const auto before = std::filesystem::file_size(copy);
  o = options(copy.string(), "input.tif");
  run = shadow(o);
  EXPECT_EQ(run.code, 2);
  EXPECT_NE(run.err.find("is the input DEM"), std::string::npos) << run.err;
  EXPECT_EQ(std::filesystem::file_size(copy), before);
  o = options(copy.string(), "other.tif");
  o.png = copy.string();
  EXPECT_EQ(shadow(o).code, 2);
  // --tz alone, a time without a zone, and a date that does not exist.
  o = options(helens, "t.tif");
  o.tz = "+02:00";
  EXPECT_NE(shadow(o).err.find("--tz needs --time"), std::string::npos);
  o.time = "2024-02-30T12:00";
  EXPECT_NE(shadow(o).err.find("no such date"), std::string::npos);
  o.tz.clear();
  o.time = "2024-06-21T12:00";
  EXPECT_NE(shadow(o).err.find("no UTC offset"), std::string::npos);
}

TEST(ShadowTool, TinyAltitudePrintsNumbers) {
  // A sun a hair above the horizon: the shadow reach is astronomical, printed as a number.
  ShadowOptions o = options(QOTA_DATA_DIR "/SainteHelens.dem", "tiny.tif");
  o.quiet = false;
  o.azimuth = 200;
  o.altitude = 1e-300;
  const ShadowRun run = shadow(o);
  ASSERT_EQ(run.code, 0) << run.err;
  for (char ch : run.out) EXPECT_TRUE(ch == '\n' || (ch >= 32 && ch < 127)) << static_cast<int>(ch);
  EXPECT_TRUE(std::regex_search(run.out, std::regex("shadow reach: [0-9.]+e\\+[0-9]+ m"))) << run.out;
}

// By tiles: every pixel as the whole raster's run, the mask and the hours, for tile sizes that do
// and do not divide the raster, with the DEM's own voids across tile edges.
TEST(ShadowTool, TilesEqualTheWholeRaster) {
  const RasterValues rainier = qota::test::readRaster(QOTA_DATA_DIR "/mt_rainier_90m.tif");
  const std::string dem = crop(rainier, "EPSG:4326", 380, 700, 420, 690, "tool_tiles_dem.tif", -32768);
  for (const auto& [azimuth, altitude] : std::vector<std::pair<double, double>>{{315, 7}, {140, 40}}) {
    ShadowOptions whole = options(dem, "tool_tiles_whole.tif");
    whole.azimuth = azimuth, whole.altitude = altitude;
    ASSERT_EQ(shadow(whole).code, 0);
    const RasterValues expected = qota::test::readRaster(whole.output);
    for (int side : {64, 128, 320}) {
      ShadowOptions tiled = whole;
      tiled.output = scratchPath("tool_tiles_tiled.tif").string();
      tiled.tileSize = side;
      const ShadowRun run = shadow(tiled);
      ASSERT_EQ(run.code, 0) << run.err;
      const RasterValues got = qota::test::readRaster(tiled.output);
      ASSERT_EQ(got.values.size(), expected.values.size());
      EXPECT_EQ(got.geotransform, expected.geotransform);
      EXPECT_TRUE(got.values == expected.values) << azimuth << "/" << altitude << ", tiles of " << side;
    }
  }
  ShadowOptions whole = options(dem, "tool_tiles_hours_whole.tif");
  whole.time = "2024-06-21";
  whole.tz = "America/Los_Angeles";
  whole.hours = std::array<double, 3>{6, 20, 2};
  ASSERT_EQ(shadow(whole).code, 0);
  ShadowOptions tiled = whole;
  tiled.output = scratchPath("tool_tiles_hours_tiled.tif").string();
  tiled.tileSize = 96;
  const ShadowRun run = shadow(tiled);
  ASSERT_EQ(run.code, 0) << run.err;
  EXPECT_TRUE(qota::test::readRaster(tiled.output).values == qota::test::readRaster(whole.output).values);
}

// One tile per run (for a batch scheduler), assembled: the whole raster's values, as a GeoTIFF
// and as a VRT; a missing tile, a tile twice and a tile off the grid are errors naming them.
TEST(ShadowTool, TilesForBatchSchedulersAssemble) {
  const RasterValues rainier = qota::test::readRaster(QOTA_DATA_DIR "/mt_rainier_90m.tif");
  const std::string dem = crop(rainier, "EPSG:4326", 400, 610, 450, 630, "tool_batch_dem.tif", -32768);
  ShadowOptions whole = options(dem, "tool_batch_whole.tif");
  whole.azimuth = 250, whole.altitude = 12;
  ASSERT_EQ(shadow(whole).code, 0);
  const RasterValues expected = qota::test::readRaster(whole.output);
  std::vector<std::string> tiles;
  // The jobs share the pass over the heights: the first makes it, the others read it.
  const std::string state = scratchPath("tool_batch_state.txt").string();
  std::filesystem::remove(state);
  for (int row = 0; row < 3; ++row) {
    for (int col = 0; col < 4; ++col) {
      ShadowOptions one = whole;
      one.output = scratchPath("tool_batch_" + std::to_string(col) + "_" + std::to_string(row) + ".tif").string();
      one.tileSize = 64;
      one.tile = std::array<int, 2>{col, row};
      one.tilesState = state;
      const ShadowRun run = shadow(one);
      ASSERT_EQ(run.code, 0) << run.err;
      tiles.push_back(one.output);
    }
  }
  const auto assemble = [](const std::vector<std::string>& from, const std::string& to) {
    qota::tools::AssembleOptions a;
    a.tiles = from;
    a.output = scratchPath(to).string();
    a.quiet = true;
    std::ostringstream out, err;
    const int code = qota::tools::assemble(a, out, err);
    return ShadowRun{code, out.str(), err.str()};
  };
  for (const char* name : {"tool_batch_all.tif", "tool_batch_all.vrt"}) {
    const ShadowRun run = assemble(tiles, name);
    ASSERT_EQ(run.code, 0) << run.err;
    const RasterValues got = qota::test::readRaster(scratchPath(name).string());
    EXPECT_EQ(got.geotransform, expected.geotransform) << name;
    EXPECT_TRUE(got.values == expected.values) << name;
  }
  // Tile 3,2 missing: named, nothing written.
  std::vector<std::string> some(tiles.begin(), tiles.end() - 1);
  std::filesystem::remove(scratchPath("tool_batch_missing.tif"));
  ShadowRun run = assemble(some, "tool_batch_missing.tif");
  EXPECT_EQ(run.code, 2);
  EXPECT_NE(run.err.find("--tile 3,2"), std::string::npos) << run.err;
  EXPECT_FALSE(std::filesystem::exists(scratchPath("tool_batch_missing.tif")));
  some.push_back(tiles[0]);
  run = assemble(some, "tool_batch_twice.tif");
  EXPECT_NE(run.err.find("given twice"), std::string::npos) << run.err;
  // A tile from another run (another tile grid), and one past the grid's end.
  ShadowOptions other = whole;
  other.output = scratchPath("tool_batch_other.tif").string();
  other.tileSize = 32;
  other.tile = std::array<int, 2>{0, 0};
  ASSERT_EQ(shadow(other).code, 0);
  some = tiles;
  some[0] = other.output;
  run = assemble(some, "tool_batch_other_all.tif");
  EXPECT_NE(run.err.find("from another run"), std::string::npos) << run.err;
  other.tile = std::array<int, 2>{7, 0};
  run = shadow(other);
  EXPECT_EQ(run.code, 2);
  EXPECT_NE(run.err.find("columns 0..6"), std::string::npos) << run.err;
  // The state of another raster, or of other frame options, is refused.
  ASSERT_TRUE(std::filesystem::exists(state));
  other = options(QOTA_DATA_DIR "/mt_rainier_90m.tif", "tool_batch_wrong_state.tif");
  other.altitude = 12, other.tileSize = 64, other.tile = std::array<int, 2>{0, 0}, other.tilesState = state;
  run = shadow(other);
  EXPECT_EQ(run.code, 2);
  EXPECT_NE(run.err.find("not the raster of the shadow tiles' state"), std::string::npos) << run.err;
  other = whole;
  other.output = scratchPath("tool_batch_wrong_options.tif").string();
  other.tileSize = 64, other.tile = std::array<int, 2>{0, 0}, other.tilesState = state, other.zFactor = 2;
  run = shadow(other);
  EXPECT_NE(run.err.find("other frame options"), std::string::npos) << run.err;
}

TEST(ShadowTool, MemoryLimitsAndTileOptionsAreChecked) {
  ShadowOptions o = options(QOTA_DATA_DIR "/mt_rainier_90m.tif", "tool_memory.tif");
  o.altitude = 20;
  o.maxMemory = 30ull << 20;  // less than the process itself
  ShadowRun run = shadow(o);
  EXPECT_EQ(run.code, 2);
  EXPECT_NE(run.err.find("allow at least"), std::string::npos) << run.err;
  // A budget the whole raster does not fit in: by tiles, within it.
  o.maxMemory = 160ull << 20;
  o.quiet = false;
  run = shadow(o);
  ASSERT_EQ(run.code, 0) << run.err;
  EXPECT_NE(run.out.find("by tiles"), std::string::npos) << run.out;
  o.quiet = true;
  o.maxMemory = 0;
  o.tileSize = 100;  // not a multiple of 16
  EXPECT_NE(shadow(o).err.find("multiple of 16"), std::string::npos);
  o.tileSize = 0;
  o.tile = std::array<int, 2>{0, 0};
  EXPECT_NE(shadow(o).err.find("needs --tile-size"), std::string::npos);
  o.tile.reset();
  o.tileSize = 256;
  o.png = scratchPath("tool_memory.png").string();
  EXPECT_NE(shadow(o).err.find("--png"), std::string::npos);
  o.png.clear();
  o.format = "PNG";
  EXPECT_NE(shadow(o).err.find("GeoTIFF"), std::string::npos);
  EXPECT_EQ(qota::tools::parseByteSize("64M"), 64ull << 20);
  EXPECT_EQ(qota::tools::parseByteSize("1.5GiB"), 3ull << 29);
  EXPECT_EQ(qota::tools::parseByteSize("2g"), 2ull << 30);
  EXPECT_EQ(qota::tools::parseByteSize("300000"), 300000u);
  for (const char* bad : {"", "2X", "-1G", "G", "nan", "1e30T"})
    EXPECT_THROW(qota::tools::parseByteSize(bad), qota::Error) << bad;
}

}  // namespace

namespace {

// A raster's dataset metadata and its band's description and unit, as GDAL reads them.
struct Provenance {
  std::map<std::string, std::string> items;
  std::string description, unit;
};
Provenance provenanceOf(const std::string& path) {
  std::unique_ptr<GDALDataset> ds(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER));
  Provenance p;
  if (!ds) return p;
  for (char** m = ds->GetMetadata(); m && *m; ++m) {
    const std::string item = *m;
    const auto eq = item.find('=');
    if (eq != std::string::npos) p.items[item.substr(0, eq)] = item.substr(eq + 1);
  }
  p.description = ds->GetRasterBand(1)->GetDescription();
  p.unit = ds->GetRasterBand(1)->GetUnitType();
  return p;
}

int runQota(std::vector<std::string> args) {
  args.insert(args.begin(), "qota");
  std::vector<const char*> argv;
  for (const std::string& a : args) argv.push_back(a.c_str());
  std::istringstream in;
  std::ostringstream out, err;
  const int code = qota::tools::runCli(static_cast<int>(argv.size()), argv.data(), in, out, err);
  EXPECT_EQ(code, 0) << err.str();
  return code;
}

}  // namespace

TEST(ShadowTool, OutputsRecordTheirMaking) {
  const std::string dem = QOTA_DATA_DIR "/mt_rainier_90m.tif";
  const std::string mask = scratchPath("provenance_mask.tif").string();
  runQota({"shadow", dem, "-az", "135", "-alt", "20", "-o", mask, "-q"});
  Provenance p = provenanceOf(mask);
  EXPECT_EQ(p.items["QOTA_TOOL"], "shadow");
  EXPECT_EQ(p.items["QOTA_SOURCE"], dem);
  EXPECT_EQ(p.items["QOTA_BAND"], "1");
  EXPECT_NE(p.items["QOTA_LIGHT"].find("azimuth 135.000 deg, altitude 20.000 deg"), std::string::npos)
      << p.items["QOTA_LIGHT"];
  EXPECT_EQ(p.items["QOTA_VALUES"], "lit 255, shadow 0, nodata 128");
  EXPECT_FALSE(p.items["QOTA_VERSION"].empty());
  EXPECT_EQ(p.items["QOTA_COMMAND"], "qota shadow " + dem + " -az 135 -alt 20 -o " + mask + " -q");
  EXPECT_EQ(p.description, "shadow mask");

  // Hours by tiles: every tile and the raster they make say the same, the band in hours.
  const std::string hours = scratchPath("provenance hours.tif").string();
  runQota({"shadow", dem, "--time", "2024-06-21", "--tz", "America/Los_Angeles", "--hours", "6", "20", "2",
           "--tile-size", "512", "-o", hours, "-q"});
  p = provenanceOf(hours);
  EXPECT_EQ(p.items["QOTA_TOOL"], "shadow");
  EXPECT_EQ(p.items["QOTA_TZ"], "America/Los_Angeles");
  EXPECT_EQ(p.items["QOTA_TIME"], "2024-06-21");
  EXPECT_EQ(p.items["QOTA_HOURS"], "start 6 h, end 20 h, step 2 h (local clock)");
  EXPECT_NE(p.items["QOTA_COMMAND"].find("'" + hours + "'"), std::string::npos) << p.items["QOTA_COMMAND"];
  EXPECT_EQ(p.description, "hours of direct sunlight");
  EXPECT_EQ(p.unit, "h");

  const std::string seen = scratchPath("provenance_viewshed.tif").string();
  runQota({"viewshed", dem, "--observer", "-121.78,46.83", "--oz", "2", "--md", "3000", "-o", seen, "-q"});
  p = provenanceOf(seen);
  EXPECT_EQ(p.items["QOTA_TOOL"], "viewshed");
  EXPECT_EQ(p.items["QOTA_SOURCE"], dem);
  EXPECT_EQ(p.items["QOTA_OBSERVER"], "-121.78,46.83");
  EXPECT_EQ(p.description, "viewshed");
  EXPECT_FALSE(p.items["QOTA_COMMAND"].empty());
}

TEST(ShadowTool, PreviewsShowTheMaskInColourWithALegend) {
  // The preview's pixels against the mask written beside it: blue where it says shadow, grey
  // where lit, transparent where there is no data; a legend strip below the picture.
  const RasterValues rainier = qota::test::readRaster(QOTA_DATA_DIR "/mt_rainier_90m.tif");
  const std::string dem = crop(rainier, "EPSG:4326", 150, 450, 100, 300, "preview_dem.tif", -32768);
  const std::string mask = scratchPath("preview_mask.tif").string(), png = scratchPath("preview_mask.png").string();
  runQota({"shadow", dem, "-az", "135", "-alt", "20", "-o", mask, "--png", png, "-q"});
  const RasterValues m = qota::test::readRaster(mask);
  std::unique_ptr<GDALDataset> p(GDALDataset::Open(png.c_str(), GDAL_OF_RASTER));
  ASSERT_TRUE(p);
  ASSERT_EQ(p->GetRasterCount(), 4);  // RGBA
  EXPECT_EQ(p->GetRasterXSize(), std::max(m.width, 360));
  EXPECT_GT(p->GetRasterYSize(), m.height + 30);  // the legend
  std::vector<std::uint8_t> rgba[4];
  for (int b = 0; b < 4; ++b) {
    rgba[b].resize(static_cast<std::size_t>(m.width) * m.height);
    ASSERT_EQ(p->GetRasterBand(b + 1)->RasterIO(GF_Read, 0, 0, m.width, m.height, rgba[b].data(), m.width, m.height,
                                                GDT_Byte, 0, 0),
              CE_None);
  }
  std::size_t shadow = 0, lit = 0, none = 0;
  for (std::size_t i = 0; i < rgba[0].size(); ++i) {
    const int r = rgba[0][i], g = rgba[1][i], b = rgba[2][i], a = rgba[3][i];
    if (m.values[i] == 128) {
      EXPECT_EQ(a, 0) << i;
      ++none;
    } else if (m.values[i] == 0) {
      EXPECT_TRUE(a == 255 && b > r + 20) << i << ": " << r << "," << g << "," << b;
      ++shadow;
    } else {
      EXPECT_TRUE(a == 255 && r == g && g == b) << i << ": " << r << "," << g << "," << b;
      ++lit;
    }
  }
  EXPECT_GT(shadow, 1000u);
  EXPECT_GT(lit, 1000u);
  EXPECT_GT(none, 0u);

  // A viewshed's: amber where visible.
  const std::string seen = scratchPath("preview_seen.tif").string(), seenPng = scratchPath("preview_seen.png").string();
  runQota({"viewshed", dem, "--observer", "-121.7326,46.8356", "--oz", "10", "-o", seen, "--png", seenPng, "-q"});
  const RasterValues v = qota::test::readRaster(seen);
  std::unique_ptr<GDALDataset> vp(GDALDataset::Open(seenPng.c_str(), GDAL_OF_RASTER));
  ASSERT_TRUE(vp);
  std::vector<std::uint8_t> red(rgba[0].size()), blue(rgba[0].size());
  ASSERT_EQ(
      vp->GetRasterBand(1)->RasterIO(GF_Read, 0, 0, v.width, v.height, red.data(), v.width, v.height, GDT_Byte, 0, 0),
      CE_None);
  ASSERT_EQ(
      vp->GetRasterBand(3)->RasterIO(GF_Read, 0, 0, v.width, v.height, blue.data(), v.width, v.height, GDT_Byte, 0, 0),
      CE_None);
  std::size_t visible = 0;
  for (std::size_t i = 0; i < red.size(); ++i) {
    if (v.values[i] == 128) continue;
    EXPECT_EQ(v.values[i] == 255, red[i] > blue[i] + 40) << i;
    visible += v.values[i] == 255;
  }
  EXPECT_GT(visible, 100u);
}
