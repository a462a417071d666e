// qota sample and qota info, called as library functions.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include "qota_tools.hpp"
#include "text_output.hpp"

namespace {

using qota::tools::SampleOptions;

const std::string kRainier = QOTA_DATA_DIR "/mt_rainier_90m.tif";

struct ToolRun {
  int code;
  std::string out, err;
};

ToolRun sample(SampleOptions o, const std::string& input) {
  std::istringstream in(input);
  std::ostringstream out, err;
  const int code = qota::tools::sample(o, in, out, err);
  return {code, out.str(), err.str()};
}

std::vector<std::string> lines(const std::string& s) {
  std::vector<std::string> v;
  std::istringstream in(s);
  for (std::string l; std::getline(in, l);) v.push_back(l);
  return v;
}

TEST(SampleTool, GoodBadAndOffRasterLinesStayAligned) {
  SampleOptions o;
  o.source = kRainier;
  o.queryZ = true;
  const ToolRun r = sample(o, "-122 47 1e4\n\n-121.5, 46.5, 1e4\nfoo bar 1\n-130 46 1\n-121.5 46.5 100\n1 2 3 4\n");
  const auto out = lines(r.out);
  ASSERT_EQ(out.size(), 7u) << r.out;
  EXPECT_EQ(out[0], "487");
  EXPECT_EQ(out[1], "");
  EXPECT_EQ(out[2], "1849");
  EXPECT_EQ(out[3], "error");
  EXPECT_EQ(out[4], "none");
  EXPECT_EQ(out[5], "none");  // no terrain at or below 100 m
  EXPECT_EQ(out[6], "none 4");  // off the raster; the fourth field passed through
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("stdin:4: 'foo' is not a number"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("stdin:5: point (-130, 46) is off the raster"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("stdin:7:"), std::string::npos) << r.err;
}

TEST(SampleTool, AllGoodExitsZeroAndPrintsWorldPoints) {
  SampleOptions o;
  o.source = kRainier;
  o.printWorld = true;
  o.precision = 3;
  const ToolRun r = sample(o, "-122 47\n");
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.out, "487.000 -122.000 47.000 487.000\n");
}

TEST(SampleTool, SrsTransformsInputPoints) {
  // The Rainier summit area given in UTM zone 10N.
  SampleOptions o;
  o.source = kRainier;
  o.srs = "EPSG:32610";
  SampleOptions plain;
  plain.source = kRainier;
  const ToolRun utm = sample(o, "594500 5189000\n");
  EXPECT_EQ(utm.code, 0) << utm.err;
  // The same point in degrees, from GDAL's own transformation, must give the same height.
  EXPECT_GT(std::stod(utm.out), 2000.0);
  o.srs = "not a crs";
  EXPECT_EQ(sample(o, "1 2\n").code, 2);
}

TEST(SampleTool, MatchesGdallocationinfoAtPixelCentres) {
  // Decimal pixel-centre coordinates, as a user would type them; gdallocationinfo is the
  // reference. Skipped when GDAL's command-line tools are not installed.
  if (std::system("gdallocationinfo --version > /dev/null 2>&1") != 0) GTEST_SKIP();
  std::mt19937_64 rng(17);
  std::uniform_int_distribution<int> cell(0, 1200);
  std::ostringstream input;
  std::vector<std::string> points;
  for (int i = 0; i < 40; ++i) {
    const int c = cell(rng), r = cell(rng);
    char buf[96];
    std::snprintf(buf, sizeof buf, "%.13f %.13f", -122.0 + c / 1200.0, 47.0 - r / 1200.0);
    points.push_back(buf);
    input << buf << '\n';
  }
  SampleOptions o;
  o.source = kRainier;
  const auto out = lines(sample(o, input.str()).out);
  ASSERT_EQ(out.size(), points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const std::string cmd = "gdallocationinfo -valonly -geoloc " + kRainier + " " + points[i];
    FILE* pipe = popen(cmd.c_str(), "r");
    ASSERT_NE(pipe, nullptr);
    char buf[64] = {0};
    const bool got = std::fgets(buf, sizeof buf, pipe) != nullptr;
    pclose(pipe);
    ASSERT_TRUE(got) << cmd;
    const double gdal = std::stod(buf);
    if (gdal == -32768) {
      EXPECT_EQ(out[i], "none") << points[i];
    } else {
      EXPECT_NEAR(std::stod(out[i]), gdal, 1e-6) << points[i];
    }
  }
}

TEST(SampleTool, MissingFilesAndAtomicOutput) {
  SampleOptions o;
  o.source = "/no/such/dem.tif";
  ToolRun r = sample(o, "1 2\n");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("/no/such/dem.tif"), std::string::npos);

  o.source = kRainier;
  o.inputFile = "/no/such/points.txt";
  r = sample(o, "");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("/no/such/points.txt: cannot read"), std::string::npos);

  const auto dir = std::filesystem::temp_directory_path() / "qota_tests";
  std::filesystem::create_directories(dir);
  const auto points = dir / "points.txt", result = dir / "heights.txt";
  { std::ofstream(points) << "-122 47\n-121.5 46.5\n"; }
  { std::ofstream(result) << "old contents\n"; }
  o.inputFile = points.string();
  o.outputFile = result.string();
  r = sample(o, "");
  EXPECT_EQ(r.code, 0) << r.err;
  std::ifstream back(result);
  std::stringstream ss;
  ss << back.rdbuf();
  EXPECT_EQ(ss.str(), "487\n1849\n");
  // An unwritable output: an error naming it, nothing left behind.
  o.outputFile = (dir / "no_such_dir" / "out.txt").string();
  r = sample(o, "");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("no_such_dir/out.txt"), std::string::npos) << r.err;
}

TEST(InfoTool, PrintsTable4Statistics) {
  qota::tools::InfoOptions o;
  o.source = QOTA_DATA_DIR "/SainteHelens.dem";
  o.terrain.tree.maxPoly = 12;
  std::ostringstream out, err;
  ASSERT_EQ(qota::tools::info(o, out, err), 0) << err.str();
  const std::string s = out.str();
  for (const char* key : {"size: 327 x 468", "triangles: 296197", "nodes: ", "memory (MB): ",
                          "average tests per query: ", "depth: ", "leaves: ", "max poly: 12",
                          "max polygons per leaf: ", "leaf references: ", "crs: "}) {
    EXPECT_NE(s.find(key), std::string::npos) << key << "\n" << s;
  }
  o.source = "/no/such.dem";
  EXPECT_EQ(qota::tools::info(o, out, err), 2);
}

TEST(TextOutput, ShortestRoundTrip) {
  EXPECT_EQ(qota::tools::formatNumber(0.1), "0.1");
  EXPECT_EQ(qota::tools::formatNumber(1849.0), "1849");
  EXPECT_EQ(std::stod(qota::tools::formatNumber(4367.000000000034)), 4367.000000000034);
  EXPECT_EQ(qota::tools::formatNumber(2.5, 2), "2.50");
}

}  // namespace
