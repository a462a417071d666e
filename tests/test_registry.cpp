// The mapping registry reaches every edge: each mapping it lists is reached by `qota sample
// --mapping NAME` and `qota build --mapping NAME` through the command line's own parsing, by the
// library's Terrain face, and through a tree file and back, with one answer everywhere. (Each
// mapping's answers against an independent oracle: the mapping's own suites. Python enumerates
// qota.MAPPINGS the same way: python/tests/test_mappings.py.)
#include <gtest/gtest.h>
#include <ogr_spatialref.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "qota/mapping_registry.hpp"
#include "qota/terrain_face.hpp"
#include "qota/treefile.hpp"
#include "qota_tools.hpp"
#include "raster_files.hpp"

namespace {

struct CliRun {
  int code;
  std::string out, err;
};

CliRun cli(std::vector<std::string> args, const std::string& input = "") {
  args.insert(args.begin(), "qota");
  std::vector<const char*> argv;
  for (const std::string& a : args) argv.push_back(a.c_str());
  std::istringstream in(input);
  std::ostringstream out, err;
  const int code = qota::tools::runCli(static_cast<int>(argv.size()), argv.data(), in, out, err);
  return {code, out.str(), err.str()};
}

// A point in each mapping's source coordinates over the test raster (a lon/lat raster round
// 10.2 E, 44.85 N): a map's x y in degrees, a planet's or an ellipsoid's lon lat, a station's
// angle and axial metres, the east-north-up frame's metres from the raster's centre. A mapping
// added to the registry without a point here fails below: wire it through the tool, Python and
// tree files, then add it.
const std::map<std::string, std::vector<double>> kPoints = {
    {"cartesian", {10.2, 44.85}}, {"spherical", {10.2, 44.85}}, {"cylindrical", {10, 0}},
    {"geodetic", {10.2, 44.85}},  {"enu", {120, -80}},
};

TEST(MappingRegistry, FollowsAnyMappingAndNamesEveryMapping) {
  EXPECT_EQ(qota::mappingNameList().size(), std::variant_size_v<qota::AnyMapping>);
  EXPECT_EQ(&qota::mappingEntry(""), &qota::mappingEntry("cartesian"));
  try {
    (void)qota::mappingEntry("polar");
    ADD_FAILURE() << "an unknown mapping is refused";
  } catch (const qota::Error& e) {
    for (const std::string& name : qota::mappingNameList()) {
      EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
    }
  }
  // The tool's help and choices come from the registry.
  const CliRun help = cli({"sample", "--help"});
  for (const qota::MappingEntry& e : qota::kMappingEntries) {
    EXPECT_NE(help.out.find(std::string(e.name) + " ("), std::string::npos) << e.name;
    EXPECT_NE(help.out.find(e.line), std::string::npos) << e.name;
  }
  const CliRun wrong = cli({"sample", "x.tif", "--mapping", "polar"});
  EXPECT_NE(wrong.code, 0);
  EXPECT_NE(wrong.err.find("enu"), std::string::npos) << wrong.err;
}

TEST(MappingRegistry, EveryMappingIsReachedByTheToolTheFaceAndTreeFiles) {
  qota::test::RasterSpec s;
  s.width = 40, s.height = 30;
  s.geotransform = {10.0, 0.01, 0, 45.0, 0, -0.01};
  s.crs = "EPSG:4326";
  s.bands = {{}};
  for (int r = 0; r < s.height; ++r) {
    for (int c = 0; c < s.width; ++c)
      s.bands[0].push_back(60 + 20 * std::sin(0.3 * c) + 15 * std::cos(0.2 * r) + c);  // (inside a station too)
  }
  const std::string raster = qota::test::scratchPath("registry.tif").string();
  qota::test::writeRaster(raster, s);
  for (const qota::MappingEntry& e : qota::kMappingEntries) {
    SCOPED_TRACE(e.name);
    const auto point = kPoints.find(e.name);
    ASSERT_NE(point, kPoints.end()) << "mapping " << e.name << " has no test point here";
    const double x = point->second[0], y = point->second[1];
    std::ostringstream line;
    line.precision(17);
    line << x << ' ' << y << '\n';

    // The library's face.
    qota::SourceOptions so;
    so.source = raster;
    so.mapping = e.name;
    const qota::Terrain face = qota::Terrain::open(so);
    EXPECT_STREQ(face.mapping(), e.name);
    const std::optional<double> want = face.height(x, y);
    ASSERT_TRUE(want.has_value());

    // The tool, through its command line.
    const CliRun run = cli({"sample", raster, "--mapping", e.name}, line.str());
    ASSERT_EQ(run.code, 0) << run.err;
    EXPECT_NEAR(std::stod(run.out), *want, 1e-9 * std::max(1.0, std::fabs(*want))) << run.out;

    // qota info opens it as sample and build do.
    const CliRun info = cli({"info", raster, "--mapping", e.name, "-q"});
    ASSERT_EQ(info.code, 0) << info.err;
    EXPECT_NE(info.out.find(std::string("mapping: ") + e.name), std::string::npos) << info.out;

    // So does render-tree (a picture of the tree in the mapping's (u, v)).
    const std::string png = qota::test::scratchPath(std::string("registry_") + e.name + ".png").string();
    const CliRun picture = cli({"render-tree", raster, "--mapping", e.name, "-o", png, "--size", "64", "-q"});
    EXPECT_EQ(picture.code, 0) << picture.err;
    EXPECT_TRUE(std::filesystem::exists(png));

    // A tree file built in the mapping, read back in it, by the tool and the face.
    const std::string tree = qota::test::scratchPath(std::string("registry_") + e.name + ".qota").string();
    const CliRun built = cli({"build", raster, "--mapping", e.name, "-o", tree, "-q"});
    ASSERT_EQ(built.code, 0) << built.err;
    EXPECT_STREQ(qota::mappingNameOf(qota::loadTree(tree).index), e.name);
    const CliRun treeInfo = cli({"info", tree});
    ASSERT_EQ(treeInfo.code, 0) << treeInfo.err;
    EXPECT_NE(treeInfo.out.find(std::string("mapping: ") + e.name), std::string::npos) << treeInfo.out;
    const CliRun again = cli({"sample", tree}, line.str());
    ASSERT_EQ(again.code, 0) << again.err;
    EXPECT_EQ(again.out, run.out);
    so.source = tree;
    so.mapping = "";
    EXPECT_EQ(qota::Terrain::open(so).height(x, y), want);
  }
}

// A lon/lat raster of 10 x 10 pixels of 500 m round 10.05 E, 44.95 N.
std::string flatRaster(const std::string& name) {
  qota::test::RasterSpec s;
  s.width = s.height = 10;
  s.geotransform = {10.0, 0.01, 0, 45.0, 0, -0.01};
  s.crs = "EPSG:4326";
  s.bands = {std::vector<double>(100, 500.0)};
  const std::string path = qota::test::scratchPath(name).string();
  qota::test::writeRaster(path, s);
  return path;
}

TEST(ToolsAgree, OptionsAMappingDoesNotTakeAreRefusedByName) {
  const std::string raster = flatRaster("refused.tif");
  const std::string tree = qota::test::scratchPath("refused.qota").string();
  for (const char* tool : {"info", "build", "sample", "render-tree"}) {
    SCOPED_TRACE(tool);
    auto run = [&](std::vector<std::string> more) {
      std::vector<std::string> args{tool, raster};
      if (std::string(tool) == "build") args.insert(args.end(), {"-o", tree});
      if (std::string(tool) == "render-tree") {
        args.insert(args.end(), {"-o", qota::test::scratchPath("refused.png").string(), "-q"});
      }
      args.insert(args.end(), more.begin(), more.end());
      return cli(args, "10.05 44.95\n");
    };
    const CliRun radius = run({"--mapping", "geodetic", "--radius", "6e6"});
    EXPECT_NE(radius.code, 0);
    EXPECT_NE(radius.err.find("--radius applies to the spherical or cylindrical mapping, not geodetic"),
              std::string::npos)
        << radius.err;
    const CliRun origin = run({"--mapping", "spherical", "--origin", "45,10"});
    EXPECT_NE(origin.err.find("--origin applies to the enu mapping, not spherical"), std::string::npos) << origin.err;
    const CliRun ref = run({"--height-ref", "egm96"});
    EXPECT_NE(ref.err.find("--height-ref applies to the geodetic or enu mapping, not cartesian"), std::string::npos)
        << ref.err;
    EXPECT_EQ(run({"--mapping", "enu", "--origin", "44.95,10.05,100"}).code, 0);
  }
}

TEST(ToolsAgree, SampleTakesOutputAndQuietAsEveryTool) {
  // -o/--output and -q/--quiet mean in sample what they mean in shadow, build and render-tree
  // (--output-file kept); quiet drops the note on what was assumed, never a point's problem.
  const std::string raster = flatRaster("agree.tif");
  const std::string input = "10.05 44.95\n20 20\n";
  const CliRun loud = cli({"sample", raster, "--mapping", "geodetic"}, input);
  EXPECT_NE(loud.err.find("note: "), std::string::npos) << loud.err;
  for (const char* flag : {"-o", "--output", "--output-file"}) {
    const std::string file = qota::test::scratchPath("agree.txt").string();
    const CliRun quiet = cli({"sample", raster, "--mapping", "geodetic", "-q", flag, file}, input);
    EXPECT_EQ(quiet.code, 1);  // (the second point is off the raster)
    EXPECT_EQ(quiet.err.find("note: "), std::string::npos) << quiet.err;
    EXPECT_NE(quiet.err.find("off the raster"), std::string::npos) << quiet.err;
    std::ifstream in(file);
    const std::string written((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    EXPECT_EQ(written, loud.out) << flag;
  }
}

TEST(ToolsAgree, SampleTakesGdallocationinfosSpellings) {
  // -wgs84 and -l_srs take points as gdallocationinfo does, -geoloc is the raster's own
  // georeferencing (the default). The reference: the same points put in the raster's UTM
  // coordinates by OGR here, sampled with no option.
  const std::string dem = QOTA_DATA_DIR "/SainteHelens.dem";
  const std::vector<std::pair<double, double>> lonLat = {{-122.1978, 46.1875}, {-122.2, 46.2}, {-122.15, 46.14}};
  OGRSpatialReference wgs84, utm;
  wgs84.SetFromUserInput("EPSG:4326");
  wgs84.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  ASSERT_EQ(utm.SetFromUserInput(qota::loadDem(dem).crsWkt.c_str()), OGRERR_NONE);
  utm.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  std::unique_ptr<OGRCoordinateTransformation> toUtm(OGRCreateCoordinateTransformation(&wgs84, &utm));
  ASSERT_TRUE(toUtm);
  std::ostringstream degrees, metres;
  degrees.precision(17), metres.precision(17);
  for (auto [lon, lat] : lonLat) {
    degrees << lon << ' ' << lat << '\n';
    double x = lon, y = lat;
    ASSERT_TRUE(toUtm->Transform(1, &x, &y));
    metres << x << ' ' << y << '\n';
  }
  const auto heights = [](const std::string& text) {
    std::vector<double> v;
    std::istringstream in(text);
    for (double h; in >> h;) v.push_back(h);
    return v;
  };
  const CliRun reference = cli({"sample", dem, "-geoloc"}, metres.str());
  ASSERT_EQ(reference.code, 0) << reference.err;
  const std::vector<double> want = heights(reference.out);
  ASSERT_EQ(want.size(), lonLat.size());
  for (const std::vector<std::string>& spelling :
       {std::vector<std::string>{"-wgs84"}, std::vector<std::string>{"-l_srs", "EPSG:4326"}}) {
    std::vector<std::string> args = {"sample", dem};
    args.insert(args.end(), spelling.begin(), spelling.end());
    const CliRun run = cli(args, degrees.str());
    ASSERT_EQ(run.code, 0) << spelling[0] << ": " << run.err;
    const std::vector<double> got = heights(run.out);
    ASSERT_EQ(got.size(), want.size()) << spelling[0];
    for (std::size_t i = 0; i < want.size(); ++i) EXPECT_NEAR(got[i], want[i], 1e-6) << spelling[0] << " " << i;
  }
  // -o on a character device writes there (nothing is replaced); a folder is still refused.
  const CliRun toNull = cli({"sample", dem, "-o", "/dev/null"}, metres.str());
  EXPECT_EQ(toNull.code, 0) << toNull.err;
  EXPECT_TRUE(toNull.out.empty()) << toNull.out;
  const CliRun toFolder = cli({"sample", dem, "-o", QOTA_DATA_DIR}, metres.str());
  EXPECT_EQ(toFolder.code, 2);
  EXPECT_NE(toFolder.err.find("not a regular file"), std::string::npos) << toFolder.err;
}

TEST(ToolsAgree, ShadowTakesMappingAsEveryTool) {
  // --mapping in shadow names the frame as in every tool: cartesian is --flat, geodetic the
  // ellipsoid (the default); a mapping no parallel light is cast in is refused by name.
  qota::test::RasterSpec s;
  s.width = s.height = 30;
  s.geotransform = {10.0, 0.1, 0, 46.0, 0, -0.1};  // pixels of some 8 by 11 km: curvature shows
  s.crs = "EPSG:4326";
  std::vector<double> z(900, 100.0);
  for (int r = 10; r < 13; ++r) {
    for (int c = 26; c < 29; ++c) z[static_cast<std::size_t>(r) * 30 + c] = 8000.0;  // (west: its shadow)
  }
  s.bands = {z};
  const std::string raster = qota::test::scratchPath("mapping_shadow.tif").string();
  qota::test::writeRaster(raster, s);
  auto run = [&](const std::string& name, std::vector<std::string> more) {
    const std::string out = qota::test::scratchPath(name).string();
    std::vector<std::string> args{"shadow", raster, "-o", out, "-az", "90", "-alt", "4", "-q"};
    args.insert(args.end(), more.begin(), more.end());
    const CliRun r = cli(args);
    EXPECT_EQ(r.code, 0) << r.err;
    return qota::test::readRaster(out).values;
  };
  const std::vector<double> flat = run("flat.tif", {"--flat"});
  const std::vector<double> ellipsoid = run("ellipsoid.tif", {});
  EXPECT_EQ(run("cartesian.tif", {"--mapping", "cartesian"}), flat);
  EXPECT_EQ(run("geodetic.tif", {"--mapping", "geodetic"}), ellipsoid);
  EXPECT_NE(flat, ellipsoid);  // (the ellipsoid shortens the shadow by a pixel: --mapping is not ignored)
  const std::string out = qota::test::scratchPath("refused_shadow.tif").string();
  const CliRun spherical = cli({"shadow", raster, "-o", out, "-az", "90", "-alt", "4", "--mapping", "spherical"});
  EXPECT_EQ(spherical.code, 2);
  EXPECT_NE(spherical.err.find("--mapping spherical: qota shadow places a DEM on its ellipsoid"), std::string::npos)
      << spherical.err;
  const CliRun both = cli({"shadow", raster, "-o", out, "-az", "90", "-alt", "4", "--mapping", "geodetic", "--flat"});
  EXPECT_EQ(both.code, 2);
  EXPECT_NE(both.err.find("give one"), std::string::npos) << both.err;
  EXPECT_FALSE(std::filesystem::exists(out));
}

}  // namespace
