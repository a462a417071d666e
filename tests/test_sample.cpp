// qota sample's answers against computations that do not use qota: brute force over a file's own
// faces, ray-triangle intersection over a raster's documented triangulation, GDAL's reads, and
// printf's exact decimal expansions.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iomanip>
#include <random>
#include <sstream>

#include "qota_tools.hpp"
#include "raster_files.hpp"
#include "text_output.hpp"

namespace {

using qota::test::linesOf;
using qota::test::scratchPath;
using qota::tools::SampleOptions;

struct ToolRun {
  int code;
  std::string out, err;
};

ToolRun sample(const SampleOptions& o, const std::string& input) {
  std::istringstream in(input);
  std::ostringstream out, err;
  const int code = qota::tools::sample(o, in, out, err);
  return {code, out.str(), err.str()};
}

SampleOptions on(const std::string& source) {
  SampleOptions o;
  o.source = source;
  return o;
}

// Moller-Trumbore with closed edges: the t > 0 at which origin + t dir meets the triangle.
std::optional<double> rayTriangle(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, const Eigen::Vector3d& a,
                                  const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const Eigen::Vector3d e1 = b - a, e2 = c - a, p = dir.cross(e2);
  const double det = e1.dot(p);
  if (det == 0) return std::nullopt;
  const Eigen::Vector3d s = origin - a;
  const double u = s.dot(p) / det;
  const Eigen::Vector3d q = s.cross(e1);
  const double v = dir.dot(q) / det, t = e2.dot(q) / det;
  const double tol = 1e-12;
  if (u < -tol || v < -tol || u + v > 1 + tol || !(t > 0)) return std::nullopt;
  return t;
}

// The faces of an OBJ file read here, without qota: "v x y z" and "f i j k ..." lines.
struct ObjFile {
  std::vector<Eigen::Vector3d> v;
  std::vector<std::vector<int>> f;
};
ObjFile readObj(const std::string& path) {
  ObjFile obj;
  std::ifstream in(path);
  for (std::string line; std::getline(in, line);) {
    std::istringstream s(line);
    std::string key;
    s >> key;
    if (key == "v") {
      Eigen::Vector3d p;
      s >> p.x() >> p.y() >> p.z();
      obj.v.push_back(p);
    } else if (key == "f") {
      std::vector<int> face;
      for (std::string t; s >> t;) face.push_back(std::stoi(t.substr(0, t.find('/'))) - 1);
      obj.f.push_back(face);
    }
  }
  return obj;
}

// The topmost face over (x, y): barycentric interpolation over each face's fan; `unclear` when
// the point is within `margin` (metres) of an edge of a face it may be in.
std::optional<double> topOfObj(const ObjFile& obj, double x, double y, double margin, bool& unclear) {
  std::optional<double> top;
  unclear = false;
  for (const auto& face : obj.f) {
    for (std::size_t k = 1; k + 1 < face.size(); ++k) {
      const Eigen::Vector3d &a = obj.v[face[0]], &b = obj.v[face[k]], &c = obj.v[face[k + 1]];
      const double area = (b.x() - a.x()) * (c.y() - a.y()) - (b.y() - a.y()) * (c.x() - a.x());
      if (area == 0) continue;  // a wall: no area seen from above
      const double wa = ((b.x() - x) * (c.y() - y) - (b.y() - y) * (c.x() - x)) / area;
      const double wb = ((c.x() - x) * (a.y() - y) - (c.y() - y) * (a.x() - x)) / area;
      const double wc = 1 - wa - wb;
      const double inside = std::min({wa, wb, wc}) * std::sqrt(std::fabs(area));
      if (std::fabs(inside) < margin) unclear = true;
      if (inside >= 0) {
        const double z = wa * a.z() + wb * b.z() + wc * c.z();
        top = top ? std::max(*top, z) : z;
      }
    }
  }
  return top;
}

TEST(SampleTool, MeshHeightsAreTheFilesOwn) {
  // Random points over the Delft block (an OBJ in map coordinates, 0.5 to 13.6 m high): the topmost
  // face's height, in the file's own z, as a brute force over its faces gives it; and the same
  // from a tree file built from it.
  const std::string path = QOTA_DATA_DIR "/testarea.obj";
  const ObjFile obj = readObj(path);
  ASSERT_EQ(obj.f.size(), 28619u);
  std::mt19937_64 rng(15);
  std::uniform_real_distribution<double> x(84616.5, 85140.8), y(447423.0, 447750.6);
  std::ostringstream input;
  std::vector<std::optional<double>> expected;
  while (expected.size() < 600) {
    const double px = x(rng), py = y(rng);
    bool unclear = false;
    const auto top = topOfObj(obj, px, py, 1e-6, unclear);
    if (unclear) continue;
    char buf[80];
    std::snprintf(buf, sizeof buf, "%.17g %.17g\n", px, py);
    input << buf;
    expected.push_back(top);
  }
  const auto tree = scratchPath("delft.qota");
  qota::tools::BuildOptions b;
  b.source.source = path;
  b.output = tree.string();
  b.quiet = true;
  std::ostringstream bo, be;
  ASSERT_EQ(qota::tools::build(b, bo, be), 0) << be.str();
  for (const std::string& source : {path, tree.string()}) {
    const ToolRun r = sample(on(source), input.str());
    const auto out = linesOf(r.out);
    ASSERT_EQ(out.size(), expected.size()) << source;
    int hits = 0;
    for (std::size_t i = 0; i < out.size(); ++i) {
      if (!expected[i]) {
        EXPECT_EQ(out[i], "none") << source << " line " << i + 1;
        continue;
      }
      ++hits;
      EXPECT_NEAR(std::stod(out[i]), *expected[i], 1e-9) << source << " line " << i + 1;
    }
    EXPECT_GT(hits, 100) << source;
  }
}

TEST(SampleTool, FlatSquareAt100OnEveryLoader) {
  // The same square, 10 m wide at z = 100, in map coordinates, through qota's OBJ reader, Assimp
  // (PLY) and OGR (GeoJSON Polygon Z): 100 everywhere on it, none beside it.
  const auto obj = scratchPath("square.obj"), ply = scratchPath("square.ply"), json = scratchPath("square.geojson");
  std::ofstream(obj) << "v 500000 5200000 100\nv 500010 5200000 100\nv 500010 5200010 100\nv 500000 5200010 100\n"
                        "f 1 2 3 4\n";
  std::ofstream(ply) << "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
                        "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
                        "0 0 100\n10 0 100\n10 10 100\n0 10 100\n4 0 1 2 3\n";
  std::ofstream(json) << R"({"type":"FeatureCollection","features":[{"type":"Feature","properties":{},)"
                         R"("geometry":{"type":"Polygon","coordinates":[[[500000,5200000,100],[500010,5200000,100],)"
                         R"([500010,5200010,100],[500000,5200010,100],[500000,5200000,100]]]}}]})";
  for (const auto& [file, x0, y0] : {std::tuple{obj.string(), 500000.0, 5200000.0}, std::tuple{ply.string(), 0.0, 0.0},
                                     std::tuple{json.string(), 500000.0, 5200000.0}}) {
    char in[160];
    std::snprintf(in, sizeof in, "%.3f %.3f\n%.3f %.3f\n%.3f %.3f 150\n%.3f %.3f\n", x0 + 5, y0 + 5, x0 + 0.25,
                  y0 + 9.5, x0 + 3, y0 + 3, x0 + 20, y0 + 5);
    SampleOptions o = on(file);
    const ToolRun r = sample(o, in);
    EXPECT_EQ(r.out, "100\n100\n100 150\nnone\n") << file << "\n" << r.err;
    // With --query-z: the terrain at or below z.
    o.queryZ = true;
    std::snprintf(in, sizeof in, "%.3f %.3f 99\n%.3f %.3f 100\n%.3f %.3f 1e6\n", x0 + 5, y0 + 5, x0 + 5, y0 + 5, x0 + 5,
                  y0 + 5);
    EXPECT_EQ(sample(o, in).out, "none\n100\n100\n") << file;
  }
}

TEST(SampleTool, QueryLinesPassFieldsThrough) {
  const std::string dem = QOTA_DATA_DIR "/mt_rainier_90m.tif";
  SampleOptions o = on(dem);
  // Fields after x y are passed through behind the separator that followed the coordinates;
  // a third number is not a query height unless --query-z.
  ToolRun r = sample(o, "-122 47 id7\n-121.5,46.5,100,x\n-121.5\t46.5\tname\n-130 46 far\n");
  EXPECT_EQ(r.out, "487 id7\n1849,100,x\n1849\tname\nnone far\n");
  EXPECT_EQ(r.code, 1);  // the off-raster line
  o.queryZ = true;
  r = sample(o, "-121.5 46.5 100 a b\n-121.5 46.5 2000\n-121.5 46.5\n");
  EXPECT_EQ(r.out, "none a b\n1849\nerror\n");
  EXPECT_NE(r.err.find("stdin:3: expected 'x y z' (--query-z), got 2 values"), std::string::npos) << r.err;
  // A header is named in the error unless --header skips it (and names the answer's column).
  o.queryZ = false;
  r = sample(o, "lon,lat,site\n-121.5,46.5,centre\n");
  EXPECT_EQ(r.out, "error\n1849,centre\n");
  EXPECT_NE(r.err.find("stdin:1: 'lon' is not a number (a header line? --header skips it)"), std::string::npos)
      << r.err;
  o.header = true;
  o.printWorld = true;
  r = sample(o, "lon,lat,site\n-121.5,46.5,centre\n");
  EXPECT_EQ(r.out, "height,x,y,z,site\n1849,-121.5,46.5,1849,centre\n");
  EXPECT_EQ(r.code, 0);
}

TEST(SampleTool, BandIsChosenNotAssumed) {
  // Two bands: heights in band 2. Without -b it is an error; -b 2 gives band 2's values.
  qota::test::RasterSpec s;
  s.width = s.height = 3;
  s.geotransform = {0, 1, 0, 3, 0, -1};
  s.crs = "EPSG:32610";
  s.bands = {std::vector<double>(9, 7.0), {1, 2, 3, 4, 5, 6, 7, 8, 9}};
  const auto path = scratchPath("two_bands.tif");
  qota::test::writeRaster(path, s);
  SampleOptions o = on(path.string());
  ToolRun r = sample(o, "1.5 1.5\n");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("has 2 bands"), std::string::npos) << r.err;
  o.band = 2;
  r = sample(o, "1.5 1.5\n0.5 2.5\n");
  EXPECT_EQ(r.out, "5\n1\n") << r.err;
  o.band = 3;
  EXPECT_EQ(sample(o, "1.5 1.5\n").code, 2);
}

// The height of the raster's surface at pixel coordinates (col, row) by the documented rule,
// computed here: clamp to the outermost centres, then the triangle of the square holding it.
double surfaceAt(const qota::test::RasterValues& r, double col, double row) {
  const double c = std::clamp(col, 0.5, r.width - 0.5) - 0.5, w = std::clamp(row, 0.5, r.height - 0.5) - 0.5;
  const int c0 = std::min(static_cast<int>(c), r.width - 2), r0 = std::min(static_cast<int>(w), r.height - 2);
  const double fc = c - c0, fr = w - r0;
  const double tl = r.at(c0, r0), tr = r.at(c0 + 1, r0), bl = r.at(c0, r0 + 1), br = r.at(c0 + 1, r0 + 1);
  // (TL, BL, BR) below the diagonal (fr >= fc), (TL, BR, TR) above it.
  if (fr >= fc) return tl + fr * (bl - tl) + fc * (br - bl);
  return tl + fc * (tr - tl) + fr * (br - tr);
}

TEST(SampleTool, OuterHalfPixelAnswersAndTilesMeet) {
  // A 6 x 4 raster cut into two 3 x 4 tiles that share an edge: every point of each tile,
  // its outer half pixel included, answers, with the clamped height; points on the shared edge
  // get an answer from both tiles.
  qota::test::RasterSpec whole;
  whole.width = 6, whole.height = 4;
  whole.geotransform = {1000, 10, 0, 2000, 0, -10};
  whole.crs = "EPSG:32610";
  whole.bands = {{11, 13, 17, 19, 23, 29, 31, 37, 41, 43, 47, 53, 59, 61, 67, 71, 73, 79, 83, 89, 97, 101, 103, 107}};
  qota::test::RasterSpec left = whole, right = whole;
  left.width = right.width = 3;
  left.bands = right.bands = {{}};
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 3; ++c) {
      left.bands[0].push_back(whole.bands[0][r * 6 + c]);
      right.bands[0].push_back(whole.bands[0][r * 6 + c + 3]);
    }
  }
  right.geotransform[0] = 1030;
  const auto lp = scratchPath("tile_left.tif"), rp = scratchPath("tile_right.tif");
  qota::test::writeRaster(lp, left);
  qota::test::writeRaster(rp, right);
  const qota::test::RasterValues lv = qota::test::readRaster(lp.string()), rv = qota::test::readRaster(rp.string());
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> col(0, 3), row(0, 4);
  for (const auto& [path, values, x0] : {std::tuple{lp.string(), &lv, 1000.0}, std::tuple{rp.string(), &rv, 1030.0}}) {
    std::ostringstream in;
    std::vector<double> expect;
    std::uniform_real_distribution<double> half(0, 0.5);
    for (int i = 0; i < 300; ++i) {
      // Most points in the outer half pixel (beside one edge or in a corner), a few exactly on
      // the raster's edges and corners, the rest anywhere.
      double c = col(rng), r = row(rng);
      if (i % 3 == 0) c = i % 2 ? half(rng) : 3 - half(rng);
      if (i % 5 < 2) r = i % 2 ? half(rng) : 4 - half(rng);
      if (i < 8) c = (i & 1) ? 3.0 : 0.0, r = (i & 2) ? 4.0 : (i & 4 ? 2.25 : 0.0);
      char buf[96];
      std::snprintf(buf, sizeof buf, "%.17g %.17g\n", x0 + 10 * c, 2000 - 10 * r);
      in << buf;
      expect.push_back(surfaceAt(*values, c, r));
    }
    const ToolRun run = sample(on(path), in.str());
    EXPECT_EQ(run.code, 0) << run.err;
    const auto out = linesOf(run.out);
    ASSERT_EQ(out.size(), expect.size());
    for (std::size_t i = 0; i < out.size(); ++i) EXPECT_NEAR(std::stod(out[i]), expect[i], 1e-9) << path << " " << i;
  }
  // Just off the raster is still off it.
  const ToolRun off = sample(on(lp.string()), "999.999 1990\n");
  EXPECT_EQ(off.out, "none\n");
  EXPECT_EQ(off.code, 1);
  // The same rule through a tree file built from the raster.
  const auto tree = scratchPath("tile_left.qota");
  qota::tools::BuildOptions b;
  b.source.source = lp.string();
  b.output = tree.string();
  b.quiet = true;
  std::ostringstream bo, be;
  ASSERT_EQ(qota::tools::build(b, bo, be), 0) << be.str();
  const auto fromTree = linesOf(sample(on(tree.string()), "1000 2000\n1029 1961\n").out);
  ASSERT_EQ(fromTree.size(), 2u);
  EXPECT_NEAR(std::stod(fromTree[0]), lv.at(0, 0), 1e-9);
  EXPECT_NEAR(std::stod(fromTree[1]), surfaceAt(lv, 2.9, 3.9), 1e-9);
}

TEST(SampleTool, PrecisionPrintsEveryDigitAskedFor) {
  // -p N prints N decimals of the double's exact value (what printf prints), up to 100.
  SampleOptions o = on(QOTA_DATA_DIR "/mt_rainier_90m.tif");
  o.precision = 40;  // (more than enough decimals to read the double back exactly)
  const double value = std::stod(sample(o, "-121.7603 46.8529\n").out);
  // The plane's height between integer pixel values, a few units in its last place off 4367
  // (the interpolation's rounding); the shortest form rounds that noise away on an integer
  // raster, -p prints every digit.
  EXPECT_NE(value, 4367.0);
  EXPECT_NEAR(value, 4367.0, 1e-9);
  o.precision = -1;
  EXPECT_EQ(sample(o, "-121.7603 46.8529\n").out, "4367\n");
  for (int p : {0, 3, 17, 60, 100}) {
    o.precision = p;
    char buf[512];
    std::snprintf(buf, sizeof buf, "%.*f\n", p, value);
    EXPECT_EQ(sample(o, "-121.7603 46.8529\n").out, buf) << p;
  }
  o.precision = 101;
  const ToolRun bad = sample(o, "1 2\n");
  EXPECT_EQ(bad.code, 2);
  EXPECT_EQ(bad.out, "");
  EXPECT_EQ(qota::tools::formatNumber(1e300, 2).size(), 304u);  // 301 digits, the point, two decimals
  EXPECT_EQ(qota::tools::formatNumber(-1.5e-300, 100).substr(0, 4), "-0.0");
}

TEST(SampleTool, SphericalIsTheRayTriangleBruteForce) {
  // The global DEM as a planet (radius (2a + b) / 3 of WGS84, the documented default): the
  // surface radius along the line from the centre, against the line met with the documented
  // triangles built here from the raster values (the squares around the point, the seam between
  // the last and first columns, the pole fanned to its row at the row's mean height).
  const std::string path = QOTA_DATA_DIR "/etopo20.tif";
  const qota::test::RasterValues e = qota::test::readRaster(path);
  const double a = 6378137.0, b = a * (1 - 1 / 298.257223563), R = (2 * a + b) / 3;
  const double deg = M_PI / 180;
  const auto up = [&](double lon, double lat) {
    return Eigen::Vector3d(std::cos(lat * deg) * std::cos(lon * deg), std::cos(lat * deg) * std::sin(lon * deg),
                           std::sin(lat * deg));
  };
  const auto vertex = [&](int c, int r) {
    c = (c % e.width + e.width) % e.width;
    const double lon = e.geotransform[0] + (c + 0.5) * e.geotransform[1];
    const double lat = e.geotransform[3] + (r + 0.5) * e.geotransform[5];
    return ((R + e.at(c, r)) * up(lon, lat)).eval();
  };
  const auto expected = [&](double lon, double lat) -> std::optional<double> {
    const Eigen::Vector3d d = up(lon, lat);
    const int c = static_cast<int>(std::floor((lon - e.geotransform[0]) / e.geotransform[1] - 0.5));
    const int r = static_cast<int>(std::floor((lat - e.geotransform[3]) / e.geotransform[5] - 0.5));
    for (int dr = -1; dr <= 1; ++dr) {
      for (int dc = -1; dc <= 1; ++dc) {
        const int rr = r + dr, cc = c + dc;
        if (rr < 0 || rr + 1 >= e.height) continue;
        const Eigen::Vector3d tl = vertex(cc, rr), tr = vertex(cc + 1, rr), bl = vertex(cc, rr + 1),
                              br = vertex(cc + 1, rr + 1);
        if (auto t = rayTriangle(Eigen::Vector3d::Zero(), d, tl, bl, br)) return t;
        if (auto t = rayTriangle(Eigen::Vector3d::Zero(), d, tl, br, tr)) return t;
      }
    }
    return std::nullopt;
  };
  std::vector<std::pair<double, double>> points = {
      {180, -52}, {-180, -52}, {179.9, 10.1}, {0.1, 0.1}, {86.925, 27.988}};
  std::mt19937_64 rng(90);
  std::uniform_real_distribution<double> lon(-180, 180), lat(-89.5, 89.5);
  for (int i = 0; i < 200; ++i) points.push_back({lon(rng), lat(rng)});
  std::ostringstream in;
  for (const auto& [x, y] : points) in << qota::tools::formatNumber(x) << ' ' << qota::tools::formatNumber(y) << '\n';
  in << "0 90\n";
  SampleOptions o = on(path);
  o.mapping = "spherical";
  const ToolRun run = sample(o, in.str());
  ASSERT_EQ(run.code, 0) << run.err;
  const auto out = linesOf(run.out);
  ASSERT_EQ(out.size(), points.size() + 1);
  for (std::size_t i = 0; i < points.size(); ++i) {
    const auto t = expected(points[i].first, points[i].second);
    ASSERT_TRUE(t) << points[i].first << ' ' << points[i].second;
    EXPECT_NEAR(std::stod(out[i]), *t, 1e-6) << points[i].first << ' ' << points[i].second;
  }
  double rowSum = 0;
  for (int c = 0; c < e.width; ++c) rowSum += e.at(c, 0);
  EXPECT_NEAR(std::stod(out.back()), R + rowSum / e.width, 1e-6);  // the north pole's vertex
}

TEST(SampleTool, CylindricalIsTheRayTriangleBruteForce) {
  // The Mount St. Helens DEM as the relief of a station (radius 3000 m, length 9000 m): column i
  // at angle -180 + 360 i / width around the z axis, row j at axial -4500 + 9000 j / (height - 1),
  // each vertex at distance 3000 - height from the axis; the output is the distance from the axis
  // of the floor under (angle, axial), by rays from the axis met with the triangles built here.
  const std::string path = QOTA_DATA_DIR "/SainteHelens.dem";
  const qota::test::RasterValues e = qota::test::readRaster(path);
  const double radius = 3000, length = 9000, deg = M_PI / 180;
  const auto vertex = [&](int i, int j) {
    i = (i % e.width + e.width) % e.width;
    const double value = e.at(i, j) == -32767 ? NAN : e.at(i, j);  // the DEM's nodata: a hole
    const double angle = (-180.0 + 360.0 * i / e.width) * deg, r = radius - value;
    return Eigen::Vector3d(r * std::cos(angle), r * std::sin(angle), -length / 2 + length * j / (e.height - 1));
  };
  std::vector<std::pair<double, double>> points = {{10, 0}, {370, 0}, {-179.9, 1234.5}, {179.99, -4000}};
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> angle(-180, 180), axial(-4400, 4400);
  for (int k = 0; k < 150; ++k) points.push_back({angle(rng), axial(rng)});
  std::ostringstream in;
  for (const auto& [u, v] : points) in << qota::tools::formatNumber(u) << ' ' << qota::tools::formatNumber(v) << '\n';
  SampleOptions o = on(path);
  o.mapping = "cylindrical";
  o.radius = radius;
  o.length = length;
  const ToolRun run = sample(o, in.str());
  ASSERT_EQ(run.code, 0) << run.err;
  const auto out = linesOf(run.out);
  ASSERT_EQ(out.size(), points.size());
  int hits = 0;
  for (std::size_t k = 0; k < points.size(); ++k) {
    const auto [u, v] = points[k];
    const Eigen::Vector3d origin(0, 0, v), dir(std::cos(u * deg), std::sin(u * deg), 0);
    const double fi = std::fmod(std::fmod(u + 180.0, 360.0) + 360.0, 360.0) / 360.0 * e.width;
    const double fj = (v + length / 2) / length * (e.height - 1);
    std::optional<double> t;
    for (int dj = -1; dj <= 1 && !t; ++dj) {
      for (int di = -1; di <= 1 && !t; ++di) {
        const int i = static_cast<int>(fi) + di, j = static_cast<int>(fj) + dj;
        if (j < 0 || j + 1 >= e.height) continue;
        const Eigen::Vector3d p00 = vertex(i, j), p10 = vertex(i + 1, j), p01 = vertex(i, j + 1),
                              p11 = vertex(i + 1, j + 1);
        if (p00.allFinite() && p01.allFinite() && p11.allFinite()) t = rayTriangle(origin, dir, p00, p01, p11);
        if (!t && p00.allFinite() && p11.allFinite() && p10.allFinite()) t = rayTriangle(origin, dir, p00, p11, p10);
      }
    }
    if (!t) {
      EXPECT_EQ(out[k], "none") << u << ' ' << v;
      continue;
    }
    ++hits;
    EXPECT_NEAR(std::stod(out[k]), *t, 1e-6) << u << ' ' << v;
  }
  EXPECT_GT(hits, 80);
}

}  // namespace

namespace {

// A 40834 x 40834 VRT (1.7 G pixels: the whole terrain would need about 730 GiB) made of the
// Rainier tile 34 x 34 times: sampled tile by tile, pixel centres answer the pixel values GDAL
// reads from the source tile, and a random point of a copy answers as the same point of the
// tile itself would, up to the plane's rounding at other coordinates.
TEST(SampleTool, ARasterFarLargerThanMemoryIsSampledByTiles) {
  const std::string dem = QOTA_DATA_DIR "/mt_rainier_90m.tif";
  const int n = 34, size = 1201;
  const auto vrt = scratchPath("mosaic_34x34.vrt");
  {
    std::ofstream f(vrt);
    f << "<VRTDataset rasterXSize=\"" << n * size << "\" rasterYSize=\"" << n * size << "\">\n"
      << "<SRS>EPSG:4326</SRS>\n<GeoTransform>-122.000416666666666, 0.000833333333333333, 0, "
         "47.000416666666666, 0, -0.000833333333333333</GeoTransform>\n"
      << "<VRTRasterBand dataType=\"Int16\" band=\"1\">\n";
    for (int r = 0; r < n; ++r) {
      for (int c = 0; c < n; ++c) {
        f << "<SimpleSource><SourceFilename relativeToVRT=\"0\">" << dem
          << "</SourceFilename><SourceBand>1</SourceBand>"
          << "<SrcRect xOff=\"0\" yOff=\"0\" xSize=\"" << size << "\" ySize=\"" << size << "\"/><DstRect xOff=\""
          << c * size << "\" yOff=\"" << r * size << "\" xSize=\"" << size << "\" ySize=\"" << size
          << "\"/></SimpleSource>\n";
      }
    }
    f << "</VRTRasterBand>\n</VRTDataset>\n";
  }
  const qota::test::RasterValues tile = qota::test::readRaster(dem);
  const double step = 0.000833333333333333;
  std::mt19937_64 rng(3);
  std::uniform_int_distribution<int> pick(0, size - 1), copy(0, n - 1);
  std::ostringstream in;
  std::vector<double> want;
  for (int k = 0; k < 200; ++k) {
    const int col = pick(rng), row = pick(rng), cc = copy(rng), cr = copy(rng);
    // The centre of pixel (col, row) of copy (cc, cr), with the geotransform's arithmetic.
    const double x = -122.000416666666666 + (cc * size + col + 0.5) * step;
    const double y = 47.000416666666666 + (cr * size + row + 0.5) * -step;
    in << std::setprecision(17) << x << ' ' << y << '\n';
    want.push_back(tile.values[static_cast<std::size_t>(row) * size + col]);
  }
  const ToolRun run = sample(on(vrt.string()), in.str());
  ASSERT_EQ(run.code, 0) << run.err;
  const std::vector<std::string> lines = linesOf(run.out);
  ASSERT_EQ(lines.size(), want.size());
  for (std::size_t i = 0; i < want.size(); ++i) {
    EXPECT_NEAR(std::stod(lines[i]), want[i], 1e-9) << "line " << i + 1;
  }
}

}  // namespace
