// Heights over a geoid placed on the ellipsoid, against PROJ's own transformation of EGM96
// heights to ellipsoidal ones (EPSG:4326+5773 to EPSG:4979, through PROJ's grid: the reference
// every GIS uses), and GeographicLib's geocentric conversion: the geoid's undulation, the
// surface's points in ECEF, heights printed in the source's own reference, stated references
// honoured, missing grids refused.
#include <GeographicLib/Geocentric.hpp>
#include <gdal_priv.h>
#include <gtest/gtest.h>
#include <proj.h>

#include <cmath>
#include <filesystem>
#include <array>
#include <random>
#include <sstream>

#include "qota/error.hpp"
#include "qota/geoid.hpp"
#include "qota/raster_grid.hpp"
#include "qota_tools.hpp"
#include "raster_files.hpp"

namespace {

using qota::test::RasterSpec;
using qota::test::scratchPath;

// PROJ's EGM96 height to ellipsoidal height: the undulation N = h - H at (lon, lat).
class ProjEgm96 {
 public:
  ProjEgm96() : ctx_(proj_context_create()) {
    PJ* p = proj_create_crs_to_crs(ctx_, "EPSG:4326+5773", "EPSG:4979", nullptr);
    if (p) {
      pj_ = proj_normalize_for_visualization(ctx_, p);  // longitude first
      proj_destroy(p);
    }
  }
  ~ProjEgm96() {
    proj_destroy(pj_);
    proj_context_destroy(ctx_);
  }
  bool ok() const { return pj_ != nullptr; }
  double undulation(double lon, double lat) const {
    const PJ_COORD out = proj_trans(pj_, PJ_FWD, proj_coord(lon, lat, 0, 0));
    return out.xyz.z;
  }

 private:
  PJ_CONTEXT* ctx_;
  PJ* pj_ = nullptr;
};

struct SampleRun {
  int code;
  std::string out, err;
};

SampleRun sample(qota::tools::SampleOptions o, const std::string& input) {
  std::istringstream in(input);
  std::ostringstream out, err;
  const int code = qota::tools::sample(o, in, out, err);
  return {code, out.str(), err.str()};
}

TEST(Geoid, AWindowHoldsTheWholeGridsValuesOverItsBox) {
  // A frame reads only the nodes over its raster: the same undulations there as the whole grid's
  // (the same nodes, the same arithmetic), NaN well beyond it; across the antimeridian too.
  qota::DemTerrain dem;
  const qota::HeightReference ref = qota::heightReferenceOf(dem, "egm96");
  const qota::Geoid whole(ref);
  std::mt19937_64 rng(28);
  for (const std::array<double, 4>& box :
       {std::array<double, 4>{-122.0, 46.0, -121.0, 47.0}, std::array<double, 4>{170.0, -20.0, 190.0, -10.0},
        std::array<double, 4>{-180.0, -90.0, 180.0, 90.0}}) {
    const qota::Geoid window(ref, box);
    EXPECT_LE(window.bytes(), whole.bytes());
    std::uniform_real_distribution<double> lon(box[0], box[2]), lat(box[1], box[3]);
    for (int k = 0; k < 2000; ++k) {
      const double x = lon(rng), y = lat(rng);
      ASSERT_EQ(window.undulation(x, y), whole.undulation(x, y)) << x << ", " << y;
    }
    EXPECT_EQ(window.rangeOver(box[0], box[1], box[2], box[3]), whole.rangeOver(box[0], box[1], box[2], box[3]));
  }
  const qota::Geoid rainier(ref, {-122.0, 46.0, -121.0, 47.0});
  EXPECT_LT(rainier.bytes(), 1024u);
  EXPECT_TRUE(std::isnan(rainier.undulation(0, 0)));
}

TEST(Geoid, Egm96UndulationsAreProjs) {
  const ProjEgm96 proj;
  ASSERT_TRUE(proj.ok());
  qota::DemTerrain dem;  // (no CRS: the Earth, nothing stated)
  const qota::HeightReference ref = qota::heightReferenceOf(dem, "egm96");
  ASSERT_FALSE(ref.ellipsoidal());
  const qota::Geoid geoid(ref);
  std::mt19937_64 rng(27);
  std::uniform_real_distribution<double> lon(-180, 180), lat(-90, 90);
  // Anywhere, across the antimeridian, at the poles and at grid nodes.
  std::vector<std::array<double, 2>> points{{180, 0}, {-180, 0},        {179.99, 12},   {-179.99, 12},       {0, 90},
                                            {0, -90}, {-121.75, 46.75}, {37.25, -61.5}, {-121.7603, 46.8529}};
  for (int k = 0; k < 3000; ++k) points.push_back({lon(rng), lat(rng)});
  double worst = 0;
  for (const auto& [x, y] : points) {
    const double want = proj.undulation(x, y);
    ASSERT_TRUE(std::isfinite(want)) << x << " " << y;
    worst = std::max(worst, std::fabs(geoid.undulation(x, y) - want));
  }
  EXPECT_LT(worst, 1e-3);  // metres (the grid's float values, interpolated in double on both sides)
  // The summit of Mount Rainier: the geoid is about 19 m below the ellipsoid there.
  EXPECT_NEAR(geoid.undulation(-121.7603, 46.8529), proj.undulation(-121.7603, 46.8529), 1e-3);
  EXPECT_LT(geoid.undulation(-121.7603, 46.8529), -18);
}

// A crop of the Rainier tile (columns c0.., rows r0..) with a stated CRS, written anew.
std::string crop(const std::string& name, const std::string& crs, int c0 = 500, int r0 = 500, int w = 60, int h = 50) {
  const qota::test::RasterValues r = qota::test::readRaster(QOTA_DATA_DIR "/mt_rainier_90m.tif");
  RasterSpec s;
  s.width = w, s.height = h;
  s.geotransform = r.geotransform;
  s.geotransform[0] += c0 * r.geotransform[1];
  s.geotransform[3] += r0 * r.geotransform[5];
  s.crs = crs;
  s.nodata = -32768;
  s.bands = {{}};
  for (int row = r0; row < r0 + h; ++row) {
    for (int col = c0; col < c0 + w; ++col) s.bands[0].push_back(r.at(col, row));
  }
  const std::string path = scratchPath(name).string();
  qota::test::writeRaster(path, s);
  return path;
}

TEST(Geoid, RainierOnTheEllipsoidIsOverEgm96) {
  // SRTM heights are over EGM96: each pixel centre's ECEF point is at H + N over the ellipsoid,
  // N from PROJ; the printed height is the raster's own (H), at every pixel centre.
  const ProjEgm96 proj;
  // (a third of the tile round the summit: the whole tile's geodetic index takes seconds a run)
  const std::string summit = crop("geoid_summit.tif", "EPSG:4326", 100, 0, 400, 400);
  const qota::test::RasterValues r = qota::test::readRaster(summit);
  const GeographicLib::Geocentric wgs84 = GeographicLib::Geocentric::WGS84();
  std::mt19937_64 rng(28);
  std::uniform_int_distribution<int> col(1, r.width - 2), row(1, r.height - 2);
  std::string input;
  std::vector<std::array<double, 3>> points;
  while (points.size() < 300) {
    const int c = col(rng), w = row(rng);
    const double h = r.at(c, w);
    if (h == -32768) continue;
    const double x = r.geotransform[0] + (c + 0.5) * r.geotransform[1],
                 y = r.geotransform[3] + (w + 0.5) * r.geotransform[5];
    points.push_back({x, y, h});
    std::ostringstream line;
    line.precision(17);
    line << x << ' ' << y << '\n';
    input += line.str();
  }
  qota::tools::SampleOptions o;
  o.source = summit;
  o.mapping = "geodetic";
  o.printWorld = true;
  const SampleRun run = sample(o, input);
  ASSERT_EQ(run.code, 0) << run.err;
  EXPECT_NE(run.err.find("EGM96 geoid (egm96_15.gtx); assumed"), std::string::npos) << run.err;  // said once
  std::istringstream lines(run.out);
  int answered = 0;
  for (const auto& [x, y, h] : points) {
    std::string text;
    ASSERT_TRUE(std::getline(lines, text));
    if (text == "none") continue;  // every triangle round the centre touches a void
    std::istringstream line(text);
    double height = 0, ex = 0, ey = 0, ez = 0;
    ASSERT_TRUE(line >> height >> ex >> ey >> ez) << text;
    ++answered;
    EXPECT_NEAR(height, h, 1e-6) << x << " " << y;
    double wx, wy, wz;
    wgs84.Forward(y, x, h + proj.undulation(x, y), wx, wy, wz);
    EXPECT_LT(std::hypot(ex - wx, ey - wy, ez - wz), 1e-3) << x << " " << y;
  }
  EXPECT_GT(answered, 250);
  // Over the ellipsoid when asked: the old answers, the undulation added when printed over it.
  o.printWorld = false;
  o.heightRef = "ellipsoid";
  const SampleRun ellipsoidal = sample(o, "-121.7603 46.8529\n");
  o.heightRef = "";
  o.outputHeightRef = "ellipsoid";
  const SampleRun overEllipsoid = sample(o, "-121.7603 46.8529\n");
  o.outputHeightRef = "";
  const SampleRun overGeoid = sample(o, "-121.7603 46.8529\n");
  const double n = proj.undulation(-121.7603, 46.8529);
  EXPECT_NEAR(std::stod(overEllipsoid.out), std::stod(overGeoid.out) + n, 1e-3);
  EXPECT_NEAR(std::stod(ellipsoidal.out), std::stod(overGeoid.out), 0.05);  // (the geoid's slope across a cell)
  // --query-z in the source's reference: just above the summit's surface finds it.
  o.queryZ = true;
  const SampleRun below = sample(o, "-121.7603 46.8529 " + std::to_string(std::stod(overGeoid.out) + 0.5) + "\n");
  EXPECT_EQ(below.out, overGeoid.out);
}

TEST(Geoid, StatedReferencesAreHonouredAndUnknownOnesRefused) {
  qota::tools::SampleOptions o;
  o.mapping = "geodetic";
  o.printWorld = true;
  const std::string point = "-121.56 46.56\n";
  o.source = crop("geoid_assumed.tif", "EPSG:4326");
  const SampleRun assumed = sample(o, point);
  ASSERT_EQ(assumed.code, 0) << assumed.err;
  // Stated EGM96 heights (a compound CRS): the same surface, nothing assumed.
  o.source = crop("geoid_egm96.tif", "EPSG:4326+5773");
  const SampleRun stated = sample(o, point);
  ASSERT_EQ(stated.code, 0) << stated.err;
  EXPECT_EQ(stated.out, assumed.out);
  EXPECT_EQ(stated.err.find("assumed"), std::string::npos) << stated.err;
  // EGM2008 is not packaged: refused, naming the grid and how to get it (never a silent zero).
  o.source = crop("geoid_egm2008.tif", "EPSG:4326+3855");
  SampleRun run = sample(o, point);
  EXPECT_EQ(run.code, 2);
  EXPECT_NE(run.err.find("us_nga_egm08_25.tif"), std::string::npos) << run.err;
  EXPECT_NE(run.err.find("projsync"), std::string::npos) << run.err;
  // A vertical CRS whose geoid qota does not know (NAVD88): refused, saying what to give.
  o.source = crop("geoid_navd88.tif", "EPSG:4269+5703");
  run = sample(o, point);
  EXPECT_EQ(run.code, 2);
  EXPECT_NE(run.err.find("NAVD88"), std::string::npos) << run.err;
  EXPECT_NE(run.err.find("--height-ref"), std::string::npos) << run.err;
  // "crs" asked of a raster that states none; a word that is not a reference; a map's heights.
  o.source = crop("geoid_assumed.tif", "EPSG:4326");
  o.heightRef = "crs";
  EXPECT_NE(sample(o, point).err.find("states no vertical CRS"), std::string::npos);
  o.heightRef = "egm69";
  EXPECT_NE(sample(o, point).err.find("not one of ellipsoid, egm96, egm2008, crs"), std::string::npos);
  o.heightRef = "egm96";
  o.mapping = "cartesian";
  EXPECT_NE(sample(o, point).err.find("--height-ref applies to"), std::string::npos);
}

TEST(Geoid, TreeFilesKeepTheReference) {
  const std::string raster = crop("geoid_tree.tif", "EPSG:4326");
  const std::string tree = scratchPath("geoid_tree.qota").string();
  qota::tools::BuildOptions b;
  b.source.source = raster;
  b.source.mapping = "geodetic";
  b.output = tree;
  b.quiet = true;
  std::ostringstream out, err;
  ASSERT_EQ(qota::tools::build(b, out, err), 0) << err.str();
  qota::tools::SampleOptions o;
  o.printWorld = true;
  o.source = raster;
  o.mapping = "geodetic";
  const std::string points = "-121.56 46.56\n-121.555 46.565\n";
  const SampleRun fromRaster = sample(o, points);
  o.source = tree;
  o.mapping = "";
  const SampleRun fromTree = sample(o, points);
  ASSERT_EQ(fromTree.code, 0) << fromTree.err;
  EXPECT_EQ(fromTree.out, fromRaster.out);
}

TEST(Geoid, APointBeyondTheGridIsNamedWhateverTheThreads) {
  // A geoid grid that covers every pixel centre of the raster but not its east edge (the outer
  // half pixel, placed after the pixels: in the last blocks). The frame's points are placed in
  // blocks of 65,536 on every core; the point named must be the first beyond the grid in the
  // frame's own order (a later block on another thread can fail first), and the failure a clean
  // refusal that writes nothing.
  const int w = 1200, h = 1200;  // (22 blocks: several threads)
  const std::string raster = crop("geoid_partial.tif", "EPSG:4326", 0, 0, w, h);
  const qota::test::RasterValues r = qota::test::readRaster(raster);
  const double eastCentre = r.geotransform[0] + (w - 0.5) * r.geotransform[1];
  RasterSpec g;
  g.width = 110, g.height = 60;  // nodes 0.01 degree apart, the last a little east of eastCentre
  const double lastNode = eastCentre + 0.25 * r.geotransform[1];
  g.geotransform = {lastNode - 109.5 * 0.01, 0.01, 0, 47.2, 0, -0.01};
  g.crs = "EPSG:4326";
  g.bands = {std::vector<double>(110 * 60, -19.0)};
  const std::string grid = scratchPath("geoid_partial_grid.tif").string();
  qota::test::writeRaster(grid, g);
  // The first vertex the grid does not cover: pixel centres first, then the border's vertices.
  qota::HeightReference ref;
  ref.name = "partial", ref.grid = grid;
  const qota::Geoid geoid(ref);
  const auto covered = [&](double col, double row) {
    return !std::isnan(
        geoid.undulation(r.geotransform[0] + col * r.geotransform[1], r.geotransform[3] + row * r.geotransform[5]));
  };
  for (int i = 0; i < w * h; ++i) ASSERT_TRUE(covered(i % w + 0.5, i / w + 0.5)) << i;
  std::string first;
  const qota::RasterGrid frameGrid(w, h, {.border = true});
  for (const auto& e : frameGrid.extraVertices()) {
    if (!covered(e.col, e.row)) {
      first = "pixel (" + std::to_string(e.col) + ", " + std::to_string(e.row) + ")";
      break;
    }
  }
  ASSERT_FALSE(first.empty());
  qota::tools::ShadowOptions o;
  o.source = raster;
  o.output = scratchPath("geoid_partial_out.tif").string();
  o.azimuth = 135, o.altitude = 10, o.quiet = true, o.heightRef = grid;
  for (int run = 0; run < 3; ++run) {
    std::ostringstream out, err;
    EXPECT_EQ(qota::tools::shadow(o, out, err), 2);
    EXPECT_NE(err.str().find(first + " at "), std::string::npos) << first << "\n" << err.str();
    EXPECT_NE(err.str().find("is outside the geoid grid"), std::string::npos) << err.str();
    EXPECT_FALSE(std::filesystem::exists(o.output));
  }
}

TEST(Geoid, ShadowsRecordTheirReference) {
  const std::string raster = crop("geoid_shadow.tif", "EPSG:4326");
  for (const std::string& ref : {std::string(), std::string("ellipsoid")}) {
    qota::tools::ShadowOptions o;
    o.source = raster;
    o.output = scratchPath("geoid_shadow_out.tif").string();
    o.azimuth = 135, o.altitude = 10, o.quiet = true, o.heightRef = ref;
    std::ostringstream out, err;
    ASSERT_EQ(qota::tools::shadow(o, out, err), 0) << err.str();
    std::unique_ptr<GDALDataset> ds(GDALDataset::Open(o.output.c_str(), GDAL_OF_RASTER));
    ASSERT_TRUE(ds);
    const char* frame = ds->GetMetadataItem("QOTA_FRAME");
    ASSERT_NE(frame, nullptr);
    EXPECT_NE(std::string(frame).find(ref.empty() ? "heights over the EGM96 geoid (egm96_15.gtx); assumed"
                                                  : "heights over the ellipsoid; asked"),
              std::string::npos)
        << frame;
  }
}

}  // namespace

namespace {

TEST(Geoid, MolasRadiusConventionOnASphere) {
  // MOLA's topography is "radius minus 3,396,000 m": on Mars's sphere of 3,396,190 m (the CRS's),
  // --height-ref radius:3396000 puts a height H at radius 3396000 + H, and prints H back.
  RasterSpec s;
  s.width = s.height = 20;
  s.geotransform = {10, 0.01, 0, 20, 0, -0.01};
  s.crs = "+proj=longlat +R=3396190 +no_defs";
  s.bands = {std::vector<double>(400, -2500.0)};
  const std::string path = scratchPath("mola.tif").string();
  qota::test::writeRaster(path, s);
  qota::tools::SampleOptions o;
  o.source = path;
  o.mapping = "geodetic";
  o.heightRef = "radius:3396000";
  o.printWorld = true;
  // A pixel centre: a vertex of the triangles, where the surface is the raster's height exactly
  // (between vertices the triangles are chords of the sphere, up to centimetres below it).
  const SampleRun run = sample(o, "10.105 19.895\n");
  ASSERT_EQ(run.code, 0) << run.err;
  std::istringstream line(run.out);
  double h = 0, x = 0, y = 0, z = 0;
  ASSERT_TRUE(line >> h >> x >> y >> z);
  EXPECT_NEAR(h, -2500, 1e-6);
  EXPECT_NEAR(std::sqrt(x * x + y * y + z * z), 3396000 - 2500, 1e-3);
  // On a flattened ellipsoid a sphere's heights run along radii: refused, naming the mapping that
  // takes them.
  s.crs = "+proj=longlat +a=3396190 +rf=169.894447223612 +no_defs";
  qota::test::writeRaster(path, s);
  EXPECT_NE(sample(o, "10.1 19.9\n").err.find("--mapping spherical --radius 3396000"), std::string::npos);
}

}  // namespace
