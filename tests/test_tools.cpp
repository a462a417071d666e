// qota sample, called as a library function (qota info: test_info.cpp).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include "qota_tools.hpp"
#include "raster_files.hpp"
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
  EXPECT_EQ(out[5], "none");    // no terrain at or below 100 m
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

TEST(SampleTool, LinesAcrossReadBlocksAndBatchesStayAligned) {
  // About 9 MB of input: read in blocks of 4 MB (a line split across each block boundary) and
  // answered in batches of 65,536 lines. Every line's answer is checked against the surface
  // dem.hpp documents (the triangle interpolation of GDAL's own pixel values, computed here), and
  // the bad lines' messages name their line numbers.
  const qota::test::RasterValues r = qota::test::readRaster(kRainier);
  std::mt19937_64 rng(23);
  std::uniform_real_distribution<double> where(2.0, 1197.0);
  std::ostringstream input;
  std::vector<double> want;  // NaN: none; -1: an error line; -2: a blank line
  std::vector<std::size_t> badLines;
  const char* separators[3] = {" ", ",", "\t"};
  for (std::size_t line = 1; input.tellp() < 9'000'000; ++line) {
    if (line % 5003 == 0) {
      input << "foo " << line << '\n';
      want.push_back(-1), badLines.push_back(line);
      continue;
    }
    if (line % 7919 == 0) {
      input << '\n';
      want.push_back(-2);
      continue;
    }
    // A point clearly inside a cell's half (not within 1e-3 cell of a side).
    double fc, fr;
    do {
      fc = where(rng), fr = where(rng);
    } while (std::min({fc - std::floor(fc), std::ceil(fc) - fc, fr - std::floor(fr), std::ceil(fr) - fr,
                       std::fabs((fc - std::floor(fc)) - (fr - std::floor(fr)))}) < 1e-3);
    const double x = r.geotransform[0] + (fc + 0.5) * r.geotransform[1];
    const double y = r.geotransform[3] + (fr + 0.5) * r.geotransform[5];
    char buf[96];
    std::snprintf(buf, sizeof buf, "%.12f%s%.12f%s", x, separators[line % 3], y, line % 11 == 0 ? "\r" : "");
    input << buf << '\n';
    const int c = static_cast<int>(std::floor(fc)), row = static_cast<int>(std::floor(fr));
    const double a = fc - c, b = fr - row;
    const double tl = r.at(c, row), tr = r.at(c + 1, row), bl = r.at(c, row + 1), br = r.at(c + 1, row + 1);
    const bool lower = b > a;
    const double v1 = lower ? bl : tr, w1 = lower ? b - a : a - b, w2 = lower ? a : b;
    const bool hole = tl == -32768 || v1 == -32768 || br == -32768;
    want.push_back(hole ? NAN : (1 - w1 - w2) * tl + w1 * v1 + w2 * br);
  }
  std::string text = input.str();
  text.pop_back();  // the last line without its newline
  SampleOptions o;
  o.source = kRainier;
  const ToolRun run = sample(o, text);
  EXPECT_EQ(run.code, 1);  // (the bad lines)
  const auto out = lines(run.out);
  ASSERT_EQ(out.size(), want.size());
  for (std::size_t i = 0; i < want.size(); ++i) {
    if (want[i] == -1) {
      ASSERT_EQ(out[i], "error") << "line " << i + 1;
    } else if (want[i] == -2) {
      ASSERT_EQ(out[i], "") << "line " << i + 1;
    } else if (std::isnan(want[i])) {
      ASSERT_EQ(out[i], "none") << "line " << i + 1;
    } else {
      ASSERT_NEAR(std::stod(out[i]), want[i], 1e-6) << "line " << i + 1;
    }
  }
  // The first 20 failed lines are named, then a count (repeated messages are capped).
  ASSERT_GT(badLines.size(), 20u);
  for (std::size_t k = 0; k < 20; ++k) {
    const std::size_t line = badLines[k];
    EXPECT_NE(run.err.find("stdin:" + std::to_string(line) + ": 'foo' is not a number"), std::string::npos) << line;
  }
  EXPECT_EQ(run.err.find("stdin:" + std::to_string(badLines[20]) + ":"), std::string::npos);
  EXPECT_NE(run.err.find(std::to_string(badLines.size() - 20) + " more failed lines (" +
                         std::to_string(badLines.size()) + " in all"),
            std::string::npos)
      << run.err.substr(run.err.size() > 300 ? run.err.size() - 300 : 0);
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

TEST(TextOutput, ShortestRoundTrip) {
  EXPECT_EQ(qota::tools::formatNumber(0.1), "0.1");
  EXPECT_EQ(qota::tools::formatNumber(1849.0), "1849");
  EXPECT_EQ(std::stod(qota::tools::formatNumber(4367.000000000034)), 4367.000000000034);
  EXPECT_EQ(qota::tools::formatNumber(2.5, 2), "2.50");
}

}  // namespace
