// Terrains from mesh files (the Delft city model in OBJ, small files through Assimp) and from 3D
// vector data through GDAL/OGR.
#include <assimp/defs.h>
#include <cpl_error.h>
#include <gdal_priv.h>
#include <gtest/gtest.h>
#include <ogr_geometry.h>
#include <ogr_spatialref.h>
#include <ogrsf_frmts.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "oracle.hpp"
#include "qota/dem.hpp"
#include "qota/error.hpp"
#include "qota/mesh_io.hpp"
#include "qota/terrain.hpp"

namespace {

using qota::CartesianIndex;
using qota::MeshFile;
using qota::MeshFileOptions;

const std::string kTestArea = QOTA_DATA_DIR "/testarea.obj";

// A directory of this process's own (tests may run in parallel processes), removed at the end.
std::filesystem::path scratchDir() {
  return std::filesystem::temp_directory_path() / ("qota_mesh_io_" + std::to_string(static_cast<long>(::getpid())));
}

std::filesystem::path scratch(const std::string& name) {
  std::filesystem::create_directories(scratchDir());
  return scratchDir() / name;
}

class RemoveScratch : public ::testing::Environment {
 public:
  void TearDown() override {
    std::error_code ec;
    std::filesystem::remove_all(scratchDir(), ec);
  }
};
[[maybe_unused]] const auto* const kRemoveScratch = ::testing::AddGlobalTestEnvironment(new RemoveScratch);

std::string writeText(const std::string& name, const std::string& text) {
  const auto path = scratch(name);
  std::ofstream(path, std::ios::binary) << text;
  return path.string();
}

// The message of the qota::Error that f throws ("" when it throws none).
std::string errorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const qota::Error& e) {
    return e.what();
  }
  return "";
}

// The Delft model is read once for all the tests that use it.
const MeshFile& testArea() {
  static const MeshFile file = qota::loadMeshFile(kTestArea);
  return file;
}

const CartesianIndex& testAreaIndex() {
  static const CartesianIndex index(testArea().mesh,
                                    qota::CartesianMapping(Eigen::Vector3d(0, 0, -1), testArea().origin));
  return index;
}

Eigen::Vector3d corner(const MeshFile& f, std::size_t polygon, std::size_t k) {
  return f.mesh.vertices[f.mesh.polygon(polygon)[k]];
}

std::set<std::uint32_t> cornersOf(const MeshFile& f, std::size_t polygon) {
  const auto idx = f.mesh.polygon(polygon);
  return {idx.begin(), idx.end()};
}

std::size_t sharedCorners(const MeshFile& f, std::size_t a, std::size_t b) {
  const auto ca = cornersOf(f, a), cb = cornersOf(f, b);
  std::vector<std::uint32_t> both;
  std::set_intersection(ca.begin(), ca.end(), cb.begin(), cb.end(), std::back_inserter(both));
  return both.size();
}

// The highest crossing the brute-force oracle finds, or NaN for none.
double oracleTop(const qota::test::OracleResult& r) {
  double top = NAN;
  for (const auto& h : r.hits) {
    if (!(h.height <= top)) top = h.height;
  }
  return top;
}

// ---------------------------------------------------------------------------------------------
// The Delft city model (data/SOURCES.md).

TEST(MeshIo, AssimpIsSinglePrecisionSoObjIsReadNatively) {
  // The reason for qota's own OBJ reader: Debian's Assimp stores coordinates as float, and a
  // float cannot hold the model's y = 447455.577 closer than 1/64 m. If this ever fails, Assimp
  // became double precision and could read OBJ as well (see mesh_io.hpp).
  EXPECT_EQ(sizeof(ai_real), sizeof(float));
  const float y = 447455.577f;
  EXPECT_GT(std::fabs(static_cast<double>(y) - 447455.577), 1e-3);
}

TEST(MeshIo, TestAreaCountsNamesAndSources) {
  const MeshFile& f = testArea();
  EXPECT_EQ(f.format, "obj");
  EXPECT_FALSE(f.singlePrecision);
  EXPECT_TRUE(f.crsWkt.empty());
  EXPECT_EQ(f.mesh.vertices.size(), 14760u);
  // 28,619 triangles in the file. SOURCES.md counts 5 degenerate ones; exactly 2 of them have all
  // three corners on one line in double arithmetic (lines 26994 and 26995) and are dropped. The
  // other 3 are slivers of area 1.5e-14 to 5e-7 m^2 (one collinear in decimal but not once the
  // decimals are rounded to doubles); they are kept, since dropping a polygon with any area would
  // open a crack in the surface.
  EXPECT_EQ(f.degenerate, 2u);
  EXPECT_EQ(f.mesh.polygonCount(), 28619u - 2u);
  EXPECT_TRUE(f.mesh.offsets.empty()) << "every face is a triangle";
  EXPECT_EQ(f.triangulated, 0u);
  ASSERT_EQ(f.polygonMaterial.size(), f.mesh.polygonCount());
  ASSERT_EQ(f.polygonObject.size(), f.mesh.polygonCount());
  ASSERT_EQ(f.polygonSource.size(), f.mesh.polygonCount());

  // All 14 classes of the file, in order of first use; no unnamed material.
  EXPECT_EQ(f.materials.size(), 14u);
  for (const char* m : {"Building", "BuildingWall", "Terrain", "TerrainWall", "Water", "WaterWall", "Road", "RoadWall",
                        "Forest", "Bridge", "Separation"}) {
    EXPECT_GE(f.materialIndex(m), 0) << m;
  }
  EXPECT_EQ(f.materialIndex(""), -1);
  EXPECT_EQ(f.materials[0], "Water");
  EXPECT_EQ(f.objects.size(), 570u);

  // The first face: line 14764, in object bedabd859-... with material Water.
  EXPECT_EQ(f.polygonSource[0], 14764u);
  EXPECT_EQ(f.materialOf(0), "Water");
  EXPECT_EQ(f.objectOf(0), "bedabd859-00c8-11e6-b420-2bdcc4ab5d7f");
  // The dropped faces are missing from the sources; the faces after them are there.
  const std::set<std::uint64_t> sources(f.polygonSource.begin(), f.polygonSource.end());
  EXPECT_EQ(sources.count(26994), 0u);
  EXPECT_EQ(sources.count(26995), 0u);
  EXPECT_EQ(sources.count(26996), 1u);
  EXPECT_EQ(sources.count(27000), 1u) << "the decimal-collinear sliver is kept";

  // The origin is the centre of the bounding box given in SOURCES.md.
  EXPECT_NEAR(f.origin.x(), (84616.5 + 85140.8) / 2, 0.1);
  EXPECT_NEAR(f.origin.y(), (447423.0 + 447750.6) / 2, 0.1);
  EXPECT_NEAR(f.origin.z(), (-0.47 + 13.58) / 2, 0.01);
}

TEST(MeshIo, TestAreaKeepsFullPrecision) {
  const MeshFile& f = testArea();
  // "v 85012.343 447455.577 0.880" (line 2) and the last vertex: the doubles nearest the text.
  EXPECT_EQ(f.mesh.vertices.front(), Eigen::Vector3d(85012.343, 447455.577, 0.880));
  std::ifstream in(kTestArea);
  std::string line, last;
  while (std::getline(in, line)) {
    if (line.rfind("v ", 0) == 0) last = line;
  }
  double x = 0, y = 0, z = 0;
  ASSERT_EQ(std::sscanf(last.c_str(), "v %lf %lf %lf", &x, &y, &z),
            3);  // strtod: correctly rounded
  EXPECT_EQ(f.mesh.vertices.back(), Eigen::Vector3d(x, y, z)) << last;
}

TEST(MeshIo, TestAreaSharesVertices) {
  const MeshFile& f = testArea();
  // No two vertices at one position: polygons that meet at a corner use one vertex index.
  std::set<std::array<double, 3>> positions;
  for (const auto& v : f.mesh.vertices) positions.insert({v.x(), v.y(), v.z()});
  EXPECT_EQ(positions.size(), f.mesh.vertices.size());
  // So edges are shared by index: of the ~43,000 edges only the outer rim and the corners where
  // walls meet roofs and ground at T-junctions (about 950) belong to a single triangle.
  std::map<std::pair<std::uint32_t, std::uint32_t>, int> uses;
  for (std::size_t p = 0; p < f.mesh.polygonCount(); ++p) {
    const auto idx = f.mesh.polygon(p);
    for (std::size_t k = 0; k < idx.size(); ++k) {
      const auto a = idx[k], b = idx[(k + 1) % idx.size()];
      ++uses[{std::min(a, b), std::max(a, b)}];
    }
  }
  std::size_t single = 0;
  for (const auto& [edge, n] : uses) single += n == 1;
  EXPECT_GT(uses.size(), 40000u);
  EXPECT_LT(single, 1000u);
}

TEST(MeshIo, TestAreaWallsAreVerticalAndLeftOutOfTheIndex) {
  const MeshFile& f = testArea();
  const CartesianIndex& index = testAreaIndex();
  std::size_t walls = 0, buildingWalls = 0;
  for (std::size_t p = 0; p < f.mesh.polygonCount(); ++p) {
    const std::string& m = f.materialOf(p);
    if (m.size() < 4 || m.compare(m.size() - 4, 4, "Wall") != 0) continue;
    ++walls;
    const auto idx = f.mesh.polygon(p);
    const auto xy = [&](std::uint32_t i) { return qota::Point2{f.mesh.vertices[i].x(), f.mesh.vertices[i].y()}; };
    // Vertical: the shadow on the ground has no area, exactly.
    EXPECT_EQ(qota::orient2dSign(xy(idx[0]), xy(idx[1]), xy(idx[2])), 0) << "line " << f.polygonSource[p];
    buildingWalls += m == "BuildingWall";
  }
  EXPECT_EQ(buildingWalls, 3066u);
  EXPECT_EQ(walls, 3974u);
  // Every *Wall polygon, and nothing else, is a wall for the index.
  EXPECT_EQ(index.stats().leftOut, walls);
  EXPECT_EQ(index.stats().polygons, f.mesh.polygonCount());
}

// A level polygon of `material` (area over 2 m^2) whose centroid the oracle sees unambiguously
// (well inside it, nothing else near) with this polygon on top, and (when `alone`) no other
// polygon below it: the highest such one when `highest`, else the first in the file.
std::size_t findProbe(const MeshFile& f, const std::string& material, bool alone, bool highest, Eigen::Vector3d& at) {
  std::vector<std::pair<std::size_t, Eigen::Vector3d>> candidates;
  for (std::size_t p = 0; p < f.mesh.polygonCount(); ++p) {
    if (f.materialOf(p) != material) continue;
    const Eigen::Vector3d a = corner(f, p, 0), b = corner(f, p, 1), c = corner(f, p, 2);
    const Eigen::Vector3d n = (b - a).cross(c - a);
    if (std::fabs(n.z()) < 0.99 * n.norm() || n.norm() < 4.0) continue;
    candidates.emplace_back(p, (a + b + c) / 3.0);
  }
  if (highest) {
    std::stable_sort(candidates.begin(), candidates.end(),
                     [](const auto& x, const auto& y) { return x.second.z() > y.second.z(); });
  }
  for (const auto& [p, centroid] : candidates) {
    const auto r = qota::test::bruteForce(f.mesh, Eigen::Vector3d(0, 0, -1), f.origin, centroid);
    if (r.nearestEdge < 0.05 || (alone && r.hits.size() != 1)) continue;
    const auto top = std::max_element(r.hits.begin(), r.hits.end(),
                                      [](const auto& x, const auto& y) { return x.height < y.height; });
    if (top == r.hits.end() || top->polygon != p) continue;
    at = centroid;
    return p;
  }
  return f.mesh.polygonCount();
}

TEST(MeshIo, TestAreaRoofAndGroundHeights) {
  const MeshFile& f = testArea();
  const CartesianIndex& index = testAreaIndex();

  Eigen::Vector3d roof;
  const std::size_t roofPolygon = findProbe(f, "Building", false, true, roof);
  ASSERT_LT(roofPolygon, f.mesh.polygonCount()) << "no level roof triangle found";
  const double u = roof.x() - f.origin.x(), v = roof.y() - f.origin.y();
  const auto hit = index.top(u, v);
  ASSERT_TRUE(hit);
  EXPECT_EQ(f.materialOf(hit->polygon), "Building");
  EXPECT_EQ(hit->polygon, roofPolygon);
  EXPECT_NEAR(hit->height + f.origin.z(), roof.z(), 1e-9);
  EXPECT_GT(roof.z(), 10.0) << "the highest roof, well above the ground at about 0 to 1 m";
  EXPECT_NEAR(hit->normal.z(), 1.0, 0.01);
  // Everything the line meets, as the oracle sees it (3dfier cuts the ground out under buildings).
  const auto r = qota::test::bruteForce(f.mesh, Eigen::Vector3d(0, 0, -1), f.origin, roof);
  EXPECT_EQ(index.all(u, v).size(), r.hits.size());

  Eigen::Vector3d ground;
  const std::size_t groundPolygon = findProbe(f, "Terrain", true, false, ground);
  ASSERT_LT(groundPolygon, f.mesh.polygonCount()) << "no open ground triangle found";
  const auto g = index.top(ground.x() - f.origin.x(), ground.y() - f.origin.y());
  ASSERT_TRUE(g);
  EXPECT_EQ(g->polygon, groundPolygon);
  EXPECT_EQ(f.materialOf(g->polygon), "Terrain");
  EXPECT_NEAR(g->height + f.origin.z(), ground.z(), 1e-9);
  EXPECT_EQ(index.all(ground.x() - f.origin.x(), ground.y() - f.origin.y()).size(), 1u);
}

TEST(MeshIo, TestAreaTopMatchesBruteForce) {
  const MeshFile& f = testArea();
  const CartesianIndex& index = testAreaIndex();
  const unsigned seed = 20240611;
  std::mt19937 rng(seed);
  // The model's footprint and a margin around it, where there is no terrain.
  std::uniform_real_distribution<double> x(84600.0, 85160.0), y(447410.0, 447760.0);
  int compared = 0, hits = 0;
  for (int i = 0; i < 300; ++i) {
    const Eigen::Vector3d p(x(rng), y(rng), 0.0);
    const auto r = qota::test::bruteForce(f.mesh, Eigen::Vector3d(0, 0, -1), f.origin, p);
    if (r.nearestEdge < 1e-6) continue;  // within rounding of an edge: either answer is right
    ++compared;
    const double expected = oracleTop(r);
    const auto hit = index.top(p.x() - f.origin.x(), p.y() - f.origin.y());
    if (std::isnan(expected)) {
      EXPECT_FALSE(hit) << "seed " << seed << " point " << i;
      continue;
    }
    ++hits;
    ASSERT_TRUE(hit) << "seed " << seed << " point " << i;
    EXPECT_NEAR(hit->height, expected, 1e-9) << "seed " << seed << " point " << i;
  }
  EXPECT_GT(compared, 290);
  EXPECT_GT(hits, 50) << "the model covers about a quarter of its bounding box";
}

TEST(MeshIo, KeepDegenerateKeepsThemAsWalls) {
  MeshFileOptions options;
  options.keepDegenerate = true;
  const MeshFile f = qota::loadMeshFile(kTestArea, options);
  EXPECT_EQ(f.degenerate, 2u);
  EXPECT_EQ(f.mesh.polygonCount(), 28619u);
  const CartesianIndex index(f.mesh, qota::CartesianMapping(Eigen::Vector3d(0, 0, -1), f.origin));
  EXPECT_EQ(index.stats().leftOut, 3974u + 2u);
}

// ---------------------------------------------------------------------------------------------
// OBJ syntax and errors.

TEST(MeshIo, ObjSyntax) {
  const std::string path = writeText("syntax.obj",
                                     "# corner forms, negative indices, names, polygons\r\n"
                                     "mtllib nowhere.mtl\r\n"
                                     "v 0 0 0\n"
                                     "v +1 0 0 1.0\n"  // w is allowed
                                     "v 1 1 0\n"
                                     "v 0 1 0   # comment\n"
                                     "vt 0 0\nvn 0 0 1\n"
                                     "f 1/1 2/1/1 3//1 4\n"  // a convex quad, kept whole
                                     "o second\n"
                                     "usemtl Roof\n"
                                     "v 2 0 1\n"
                                     "v 1 0 0\n"  // the same point as vertex 2: joined
                                     "f -3 -1 -2\n"
                                     "g third\n"
                                     "v 3 0 5\nv 5 0 5\nv 5 2 5\nv 4 1 5\nv 3 2 5\n"  // a dart
                                     "f 7 8 \\\n 9 10 11\n"                           // continued over two lines
                                     "l 1 2\n"
                                     "s off\n");
  const MeshFile f = qota::loadMeshFile(path);
  EXPECT_EQ(f.mesh.vertices.size(), 10u) << "vertex 6 repeats vertex 2";
  EXPECT_EQ(f.mesh.vertices[1], Eigen::Vector3d(1, 0, 0));
  // The quad, one triangle, and the non-convex dart cut into three triangles.
  ASSERT_EQ(f.mesh.polygonCount(), 5u);
  EXPECT_EQ(f.mesh.polygon(0).size(), 4u);
  EXPECT_EQ(f.triangulated, 1u);
  EXPECT_EQ(std::vector<std::uint32_t>(f.mesh.polygon(1).begin(), f.mesh.polygon(1).end()),
            (std::vector<std::uint32_t>{3, 1, 4}))
      << "-3 -1 -2 of v 0 1 0, v 1 0 0 (joined), v 2 0 1";
  EXPECT_EQ(f.materials, (std::vector<std::string>{"", "Roof"}));
  EXPECT_EQ(f.objects, (std::vector<std::string>{"", "second", "third"}));
  EXPECT_EQ(f.objectOf(4), "third");
  EXPECT_EQ(f.materialOf(4), "Roof");
  EXPECT_EQ(f.polygonSource[0], 9u);
  EXPECT_EQ(f.polygonSource[4], 21u) << "a continued statement is named by its first line";
  // The dart's triangles cover it exactly: area 2 + 2 - 1 - ... = its shoelace area, 3.
  double area = 0;
  for (std::size_t p = 2; p < 5; ++p) {
    area += 0.5 * (corner(f, p, 1) - corner(f, p, 0)).cross(corner(f, p, 2) - corner(f, p, 0)).norm();
  }
  EXPECT_DOUBLE_EQ(area, 3.0);
}

TEST(MeshIo, ObjErrorsNameFileAndLine) {
  struct Case {
    const char* text;
    const char* message;
  };
  const Case cases[] = {
      {"v 1 2\n", "bad.obj:1: a vertex needs three coordinates"},
      {"v 1 2 x\n", "bad.obj:1: 'x' is not a number"},
      {"v 1 2 nan\n", "bad.obj:1: 'nan' is not a finite number"},
      {"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n", "bad.obj:4: face corner 'x'"},
      {"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n", "bad.obj:4: a face needs at least three corners"},
      {"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n", "bad.obj:4: face corner '0': index 0"},
      {"v 0 0 0\nv 1 0 0\nv 0 1 0\n\nf 1 2 4\n", "bad.obj:5: vertex index 4 is out of range"},
      {"v 0 0 0\nv 1 0 0\nf 1 2 -3\n", "bad.obj:3: vertex index -3 is out of range"},
      {"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/x 2 3\n", "bad.obj:4: face corner '1/x'"},
      {"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3 2 1 3\n", ""},  // a bow tie of repeats: see below
      {"v 0 0 0\n", "bad.obj: no polygons"},
      {"v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n", "bad.obj: no polygons (all 1 faces are degenerate"},
      {"v 0 0 0\nv 2 0 0\nv 2 2 0\nv 0 2 0\nf 1 3 2 4\n", "bad.obj:5: cannot cut the 4-corner polygon"},
  };
  for (const auto& c : cases) {
    const std::string path = writeText("bad.obj", c.text);
    const std::string message = errorOf([&] { qota::loadMeshFile(path); });
    if (*c.message == 0) continue;  // only: no crash
    EXPECT_NE(message.find(path), std::string::npos) << c.text;
    EXPECT_NE(message.find(c.message), std::string::npos) << c.text << "\n-> " << message;
  }
}

TEST(MeshIo, MissingAndUnknownFiles) {
  const std::string missing = errorOf([] { qota::loadMeshFile("/no/such/terrain.obj"); });
  EXPECT_NE(missing.find("/no/such/terrain.obj: no such file"), std::string::npos) << missing;
  EXPECT_NE(errorOf([] { qota::loadMeshFile("/no/such/terrain.gpkg"); }).find("no such file"), std::string::npos);
  const std::string path = writeText("notes.qqq", "nothing to see\n");
  const std::string unknown = errorOf([&] { qota::loadMeshFile(path); });
  EXPECT_NE(unknown.find(path + ": unknown format"), std::string::npos) << unknown;
}

// ---------------------------------------------------------------------------------------------
// Assimp.

TEST(MeshIo, AssimpStlJoinsRepeatedCorners) {
  // STL repeats every corner in every facet; the two facets share an edge.
  const std::string path = writeText("two.stl",
                                     "solid two\n"
                                     " facet normal 0 0 1\n  outer loop\n"
                                     "   vertex 0 0 0\n   vertex 1 0 0\n   vertex 1 1 0\n"
                                     "  endloop\n endfacet\n"
                                     " facet normal 0 0 1\n  outer loop\n"
                                     "   vertex 0 0 0\n   vertex 1 1 0\n   vertex 0 1 0.5\n"
                                     "  endloop\n endfacet\n"
                                     "endsolid two\n");
  const MeshFile f = qota::loadMeshFile(path);
  EXPECT_EQ(f.format, "assimp:stl");
  EXPECT_TRUE(f.singlePrecision);
  EXPECT_EQ(f.mesh.vertices.size(), 4u);
  ASSERT_EQ(f.mesh.polygonCount(), 2u);
  EXPECT_EQ(sharedCorners(f, 0, 1), 2u);
  EXPECT_EQ(f.origin, Eigen::Vector3d(0.5, 0.5, 0.25));
}

TEST(MeshIo, AssimpOffKeepsConvexPolygons) {
  const std::string path = writeText("shapes.off",
                                     "OFF\n12 3 0\n"
                                     "0 0 0\n2 0 0\n2 2 0\n0 2 0\n"         // a square
                                     "2 0 0\n3 0 1\n2 2 0\n"                // a triangle on its edge
                                     "5 0 0\n7 0 0\n7 2 0\n6 1 0\n5 2 0\n"  // a dart
                                     "4 0 1 2 3\n3 4 5 6\n5 7 8 9 10 11\n");
  const MeshFile f = qota::loadMeshFile(path);
  EXPECT_EQ(f.format, "assimp:off");
  EXPECT_EQ(f.mesh.vertices.size(), 10u);
  ASSERT_EQ(f.mesh.polygonCount(), 1u + 1u + 3u);
  EXPECT_EQ(f.mesh.polygon(0).size(), 4u);
  EXPECT_EQ(sharedCorners(f, 0, 1), 2u);
  EXPECT_EQ(f.triangulated, 1u);
}

std::string base64(const std::vector<unsigned char>& bytes) {
  static const char* digits = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  for (std::size_t i = 0; i < bytes.size(); i += 3) {
    const unsigned n =
        (bytes[i] << 16) | ((i + 1 < bytes.size() ? bytes[i + 1] : 0) << 8) | (i + 2 < bytes.size() ? bytes[i + 2] : 0);
    out += digits[(n >> 18) & 63];
    out += digits[(n >> 12) & 63];
    out += i + 1 < bytes.size() ? digits[(n >> 6) & 63] : '=';
    out += i + 2 < bytes.size() ? digits[n & 63] : '=';
  }
  return out;
}

TEST(MeshIo, AssimpGltfMaterialsNodesAndTransforms) {
  // One triangle in a node that scales by 2 and moves it to (1000, 2000, 10).
  const float positions[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0.5f};
  const std::uint16_t indices[4] = {0, 1, 2, 0};  // padded to 4 bytes
  std::vector<unsigned char> buffer(sizeof positions + sizeof indices);
  std::memcpy(buffer.data(), positions, sizeof positions);
  std::memcpy(buffer.data() + sizeof positions, indices, sizeof indices);
  const std::string gltf = R"({"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0]}],)"
                           R"("nodes":[{"name":"house","mesh":0,"translation":[1000,2000,10],"scale":[2,2,2]}],)"
                           R"("meshes":[{"name":"roofmesh","primitives":[)"
                           R"({"attributes":{"POSITION":0},"indices":1,"material":0}]}],)"
                           R"("materials":[{"name":"Roof"}],)"
                           R"("buffers":[{"byteLength":44,"uri":"data:application/octet-stream;base64,)" +
                           base64(buffer) +
                           R"("}],"bufferViews":[{"buffer":0,"byteOffset":0,"byteLength":36},)"
                           R"({"buffer":0,"byteOffset":36,"byteLength":6}],)"
                           R"("accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3",)"
                           R"("min":[0,0,0],"max":[1,1,0.5]},)"
                           R"({"bufferView":1,"componentType":5123,"count":3,"type":"SCALAR"}]})";
  const MeshFile f = qota::loadMeshFile(writeText("roof.gltf", gltf));
  EXPECT_EQ(f.format, "assimp:gltf");
  ASSERT_EQ(f.mesh.polygonCount(), 1u);
  EXPECT_EQ(f.materialOf(0), "Roof");
  EXPECT_EQ(f.objectOf(0), "house");
  const std::set<std::array<double, 3>> got = [&] {
    std::set<std::array<double, 3>> s;
    for (const auto& v : f.mesh.vertices) s.insert({v.x(), v.y(), v.z()});
    return s;
  }();
  EXPECT_EQ(got, (std::set<std::array<double, 3>>{{1000, 2000, 10}, {1002, 2000, 10}, {1000, 2002, 11}}));
}

// ---------------------------------------------------------------------------------------------
// GDAL/OGR.

OGRLinearRing ring(std::initializer_list<std::array<double, 3>> points) {
  OGRLinearRing r;
  for (const auto& p : points) r.addPoint(p[0], p[1], p[2]);
  r.closeRings();
  return r;
}

OGRPolygon polygon(std::initializer_list<OGRLinearRing> rings) {
  OGRPolygon p;
  for (const auto& r : rings) p.addRingDirectly(r.clone());
  return p;
}

// Map coordinates in the millions with digits no float keeps (Gauss-Krueger zone 2).
constexpr double X0 = 2000000.1, Y0 = 5000000.7, Z0 = 100.3;

std::string makeGeoPackage() {
  const std::string path = scratch("surfaces.gpkg").string();
  std::filesystem::remove(path);
  qota::ensureGdalRegistered();
  GDALDriver* driver = GetGDALDriverManager()->GetDriverByName("GPKG");
  if (!driver) return "";
  std::unique_ptr<GDALDataset> ds(driver->Create(path.c_str(), 0, 0, 0, GDT_Unknown, nullptr));
  if (!ds) return "";
  OGRSpatialReference srs;
  srs.importFromEPSG(31466);
  srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  // PolyhedralSurface and TIN are GeoPackage extensions; GDAL warns that it registers them.
  CPLPushErrorHandler(CPLQuietErrorHandler);
  OGRLayer* roofs = ds->CreateLayer("roofs", &srs, wkbUnknown, nullptr);  // mixed types
  OGRLayer* tin = ds->CreateLayer("tin", &srs, wkbTINZ, nullptr);
  CPLPopErrorHandler();
  if (!roofs || !tin) return "";
  OGRFieldDefn cls("class", OFTString);
  roofs->CreateField(&cls);

  auto add = [&](OGRLayer* layer, const OGRGeometry& g, const char* value) {
    OGRFeature feature(layer->GetLayerDefn());
    feature.SetGeometry(&g);
    if (value) feature.SetField("class", value);
    CPLPushErrorHandler(CPLQuietErrorHandler);
    const OGRErr err = layer->CreateFeature(&feature);
    CPLPopErrorHandler();
    return err == OGRERR_NONE;
  };
  bool ok = true;
  // Feature 1: two planar patches sharing the edge B-C (z = Z0 + (dx + dy) / 40).
  const std::array<double, 3> A{X0, Y0, Z0}, B{X0 + 10, Y0, Z0 + 0.25}, C{X0 + 10, Y0 + 10, Z0 + 0.5},
      D{X0, Y0 + 10, Z0 + 0.25}, E{X0 + 20, Y0, Z0 + 0.5}, F{X0 + 20, Y0 + 10, Z0 + 0.75};
  OGRPolyhedralSurface surface;
  const OGRPolygon patch1 = polygon({ring({A, B, C, D})}), patch2 = polygon({ring({B, E, F, C})});
  surface.addGeometry(&patch1);
  surface.addGeometry(&patch2);
  ok &= add(roofs, surface, "roof");
  // Feature 2: a polygon sharing the edge E-F with the surface.
  const std::array<double, 3> G{X0 + 30, Y0, Z0 + 0.75}, H{X0 + 30, Y0 + 10, Z0 + 1.0};
  ok &= add(roofs, polygon({ring({E, G, H, F})}), "terrace");
  // Feature 3: a level yard with a square hole in it.
  const double x3 = X0 + 40, z3 = Z0 - 1;
  ok &=
      add(roofs,
          polygon({ring({{x3, Y0, z3}, {x3 + 20, Y0, z3}, {x3 + 20, Y0 + 20, z3}, {x3, Y0 + 20, z3}}),
                   ring({{x3 + 5, Y0 + 5, z3}, {x3 + 5, Y0 + 15, z3}, {x3 + 15, Y0 + 15, z3}, {x3 + 15, Y0 + 5, z3}})}),
          "yard");
  // Feature 4: an L-shaped (non-convex) yard.
  const double x4 = X0 + 70;
  ok &= add(roofs,
            polygon({ring({{x4, Y0, z3},
                           {x4 + 20, Y0, z3},
                           {x4 + 20, Y0 + 5, z3},
                           {x4 + 5, Y0 + 5, z3},
                           {x4 + 5, Y0 + 20, z3},
                           {x4, Y0 + 20, z3}})}),
            "yard");
  // The TIN layer: two triangles sharing an edge, away from the rest.
  const double x5 = X0 + 100;
  OGRTriangulatedSurface triangles;
  OGRPoint p0(x5, Y0, Z0), p1(x5 + 10, Y0, Z0 + 1), p2(x5 + 10, Y0 + 10, Z0 + 2), p3(x5, Y0 + 10, Z0 + 1);
  triangles.addGeometryDirectly(new OGRTriangle(p0, p1, p2));
  triangles.addGeometryDirectly(new OGRTriangle(p0, p2, p3));
  ok &= add(tin, triangles, nullptr);
  return ok ? path : "";
}

const std::string& geoPackage() {
  static const std::string path = makeGeoPackage();
  return path;
}

TEST(MeshIo, GeoPackageEveryLayer) {
  ASSERT_FALSE(geoPackage().empty()) << "could not write the GeoPackage";
  const MeshFile f = qota::loadMeshFile(geoPackage());
  EXPECT_EQ(f.format, "ogr:GPKG");
  EXPECT_FALSE(f.singlePrecision);
  // Materials are the layer names; objects the features.
  EXPECT_EQ(f.materials, (std::vector<std::string>{"roofs", "tin"}));
  EXPECT_EQ(f.objects, (std::vector<std::string>{"roofs:1", "roofs:2", "roofs:3", "roofs:4", "tin:1"}));
  // 2 patches + 1 polygon + 8 triangles around the hole + 4 for the L + 2 TIN triangles.
  ASSERT_EQ(f.mesh.polygonCount(), 17u);
  EXPECT_EQ(f.triangulated, 2u);
  EXPECT_EQ(f.degenerate, 0u);
  // Shared corners: 6 for the surface, 2 more for the terrace, 8 + 6 for the yards, 4 for the TIN.
  EXPECT_EQ(f.mesh.vertices.size(), 26u);
  EXPECT_EQ(sharedCorners(f, 0, 1), 2u) << "patches of one surface share their edge";
  EXPECT_EQ(sharedCorners(f, 1, 2), 2u) << "features share their edge";
  EXPECT_EQ(sharedCorners(f, 15, 16), 2u) << "TIN triangles share their edge";
  EXPECT_EQ(f.polygonSource[0], 1u);
  EXPECT_EQ(f.polygonSource[2], 2u);
  EXPECT_EQ(f.polygonSource[3], 3u);
  EXPECT_EQ(f.materialOf(16), "tin");
  // Exact coordinates, though no float holds them.
  EXPECT_EQ(f.mesh.vertices[0], Eigen::Vector3d(X0, Y0, Z0));
  EXPECT_NE(static_cast<double>(static_cast<float>(X0)), X0);
  EXPECT_EQ(corner(f, 1, 2), Eigen::Vector3d(X0 + 20, Y0 + 10, Z0 + 0.75));
  // The CRS came along.
  OGRSpatialReference crs;
  ASSERT_EQ(crs.importFromWkt(f.crsWkt.c_str()), OGRERR_NONE) << f.crsWkt;
  ASSERT_NE(crs.GetAuthorityCode(nullptr), nullptr);
  EXPECT_STREQ(crs.GetAuthorityCode(nullptr), "31466");
}

TEST(MeshIo, GeoPackageQueries) {
  ASSERT_FALSE(geoPackage().empty());
  const MeshFile f = qota::loadMeshFile(geoPackage());
  const CartesianIndex index(f.mesh, qota::CartesianMapping(Eigen::Vector3d(0, 0, -1), f.origin));
  const Eigen::Vector3d& o = f.origin;
  auto topAt = [&](double x, double y) { return index.top(x - o.x(), y - o.y()); };
  // Inside the first patch: its plane.
  auto hit = topAt(X0 + 2, Y0 + 6);
  ASSERT_TRUE(hit);
  EXPECT_NEAR(hit->height + o.z(), Z0 + 8.0 / 40, 1e-9);
  // On the shared edge of the two patches and of the two features: no crack.
  for (double y = Y0 + 0.5; y < Y0 + 10; y += 1.0) {
    EXPECT_TRUE(topAt(X0 + 10, y)) << y - Y0;
    EXPECT_TRUE(topAt(X0 + 20, y)) << y - Y0;
  }
  // The yard has its hole; the L has its notch.
  const double x3 = X0 + 40, x4 = X0 + 70;
  EXPECT_FALSE(topAt(x3 + 10, Y0 + 10));
  hit = topAt(x3 + 2, Y0 + 10);
  ASSERT_TRUE(hit);
  EXPECT_NEAR(hit->height + o.z(), Z0 - 1, 1e-9);
  EXPECT_EQ(f.polygonSource[hit->polygon], 3u);
  EXPECT_TRUE(topAt(x4 + 2, Y0 + 18));
  EXPECT_TRUE(topAt(x4 + 18, Y0 + 2));
  EXPECT_FALSE(topAt(x4 + 10, Y0 + 10));
}

TEST(MeshIo, GeoPackageOneLayerAndMaterialField) {
  ASSERT_FALSE(geoPackage().empty());
  MeshFileOptions options;
  options.layer = "tin";
  const MeshFile tin = qota::loadMeshFile(geoPackage(), options);
  EXPECT_EQ(tin.mesh.polygonCount(), 2u);
  EXPECT_EQ(tin.mesh.vertices.size(), 4u);
  EXPECT_EQ(tin.materials, (std::vector<std::string>{"tin"}));

  options.layer = "roofs";
  options.materialField = "class";
  const MeshFile roofs = qota::loadMeshFile(geoPackage(), options);
  EXPECT_EQ(roofs.materials, (std::vector<std::string>{"roof", "terrace", "yard"}));
  EXPECT_EQ(roofs.materialOf(0), "roof");
  EXPECT_EQ(roofs.materialOf(2), "terrace");
  EXPECT_EQ(roofs.materialOf(roofs.mesh.polygonCount() - 1), "yard");

  options.layer = "nope";
  EXPECT_NE(errorOf([&] { qota::loadMeshFile(geoPackage(), options); }).find("no layer 'nope' (layers: roofs, tin)"),
            std::string::npos);
  options.layer = "tin";  // has no "class" field
  EXPECT_NE(errorOf([&] { qota::loadMeshFile(geoPackage(), options); }).find("layer 'tin' has no field 'class'"),
            std::string::npos);
}

TEST(MeshIo, OgrRejectsFlatAndNonSurfaceGeometry) {
  const std::string flat =
      writeText("flat.geojson", R"({"type":"FeatureCollection","features":[{"type":"Feature","id":7,"properties":{},)"
                                R"("geometry":{"type":"Polygon","coordinates":[[[0,0],[1,0],[1,1],[0,0]]]}}]})");
  const std::string m1 = errorOf([&] { qota::loadMeshFile(flat); });
  EXPECT_NE(m1.find("feature 7: Polygon has no Z coordinates"), std::string::npos) << m1;
  const std::string line =
      writeText("line.geojson", R"({"type":"FeatureCollection","features":[{"type":"Feature","id":3,"properties":{},)"
                                R"("geometry":{"type":"GeometryCollection","geometries":[)"
                                R"({"type":"LineString","coordinates":[[0,0,1],[1,0,1]]}]}}]})");
  const std::string m2 = errorOf([&] { qota::loadMeshFile(line); });
  EXPECT_NE(m2.find("feature 3: 3D Line String is not a surface"), std::string::npos) << m2;
}

TEST(MeshIo, OgrVerticalWallWithWindow) {
  // A wall in the x-z plane with a window: cut in its own plane, it is all walls for the index.
  const std::string path =
      writeText("wall.geojson", R"({"type":"FeatureCollection","features":[{"type":"Feature","id":1,"properties":{},)"
                                R"("geometry":{"type":"Polygon","coordinates":[)"
                                R"([[0,5,0],[10,5,0],[10,5,6],[0,5,6],[0,5,0]],)"
                                R"([[2,5,2],[2,5,4],[5,5,4],[5,5,2],[2,5,2]]]}}]})");
  const MeshFile f = qota::loadMeshFile(path);
  ASSERT_EQ(f.mesh.polygonCount(), 8u);
  EXPECT_EQ(f.triangulated, 1u);
  double area = 0;
  for (std::size_t p = 0; p < 8; ++p) {
    area += 0.5 * (corner(f, p, 1) - corner(f, p, 0)).cross(corner(f, p, 2) - corner(f, p, 0)).norm();
  }
  EXPECT_DOUBLE_EQ(area, 60.0 - 6.0);
  const CartesianIndex index(f.mesh, qota::CartesianMapping(Eigen::Vector3d(0, 0, -1), f.origin));
  EXPECT_EQ(index.stats().leftOut, 8u);
  // Seen from the side (gravity along +y), the window is a hole.
  const CartesianIndex side(f.mesh, qota::CartesianMapping(Eigen::Vector3d(0, 1, 0), f.origin));
  EXPECT_EQ(side.stats().leftOut, 0u);
  EXPECT_TRUE(side.topWorld(Eigen::Vector3d(1, 0, 1)));
  EXPECT_FALSE(side.topWorld(Eigen::Vector3d(3.5, 0, 3)));
}

// Random star-shaped polygons, each with 0, 1 or 2 star-shaped holes, at map coordinates on a
// tilted plane: every one is cut into triangles that cover exactly its area, and the index finds
// terrain exactly where the polygon (minus its holes) is.
using Ring2 = std::vector<std::array<double, 2>>;

// n corners at jittered, increasing angles (gaps below 2 pi * 1.5 / n) around (cx, cy).
Ring2 star(std::mt19937& rng, double cx, double cy, double rmin, double rmax, int n, bool ccw) {
  std::uniform_real_distribution<double> jitter(0.0, 0.5), radius(rmin, rmax);
  Ring2 r;
  for (int i = 0; i < n; ++i) {
    const double t = 2 * M_PI * (i + jitter(rng)) / n, rr = radius(rng);
    r.push_back({cx + rr * std::cos(t), cy + rr * std::sin(t)});
  }
  if (!ccw) std::reverse(r.begin(), r.end());
  return r;
}

bool insideRing(const Ring2& r, double x, double y) {  // even-odd rule
  bool in = false;
  for (std::size_t i = 0, j = r.size() - 1; i < r.size(); j = i++) {
    if ((r[i][1] > y) != (r[j][1] > y) && x < (r[j][0] - r[i][0]) * (y - r[i][1]) / (r[j][1] - r[i][1]) + r[i][0]) {
      in = !in;
    }
  }
  return in;
}

double distanceToRing(const Ring2& r, double x, double y) {
  double best = 1e300;
  for (std::size_t i = 0, j = r.size() - 1; i < r.size(); j = i++) {
    const double ex = r[i][0] - r[j][0], ey = r[i][1] - r[j][1];
    const double t = std::clamp(((x - r[j][0]) * ex + (y - r[j][1]) * ey) / (ex * ex + ey * ey), 0.0, 1.0);
    best = std::min(best, std::hypot(x - r[j][0] - t * ex, y - r[j][1] - t * ey));
  }
  return best;
}

double ringArea(const Ring2& r) {
  double a = 0;
  for (std::size_t i = 0, j = r.size() - 1; i < r.size(); j = i++) {
    a += (r[j][0] - r[0][0]) * (r[i][1] - r[0][1]) - (r[i][0] - r[0][0]) * (r[j][1] - r[0][1]);
  }
  return std::fabs(a) / 2;
}

TEST(MeshIo, RandomPolygonsWithHolesAreCutExactly) {
  const unsigned seed = 7919;
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> corners(7, 40), holeCount(0, 2);
  const auto z = [](double x, double y) { return 100.0 + 0.1 * (x - X0) + 0.2 * (y - Y0); };
  struct Shape {
    std::vector<Ring2> rings;
    double area;
  };
  std::vector<Shape> shapes;
  std::ostringstream json;
  json.precision(17);
  json << R"({"type":"FeatureCollection","features":[)";
  for (int k = 0; k < 100; ++k) {
    // Each polygon in its own 30 m cell. Its outline has radius >= 5 m and 7 or more corners with
    // angular gaps below 77 degrees, so it holds the disc of radius 5 cos(38.5) = 3.9 m: holes
    // centred at +-2.5 m with radius <= 1.2 m stay inside it and apart from each other.
    const double cx = X0 + 30.0 * (k % 10), cy = Y0 + 30.0 * (k / 10);
    Shape s;
    s.rings.push_back(star(rng, cx, cy, 5.0, 12.0, corners(rng), true));
    const int holes = holeCount(rng);
    for (int h = 0; h < holes; ++h) {
      s.rings.push_back(star(rng, cx + (h ? -2.5 : 2.5), cy, 0.3, 1.2, corners(rng), h % 2 == 0));
    }
    s.area = ringArea(s.rings[0]);
    for (std::size_t h = 1; h < s.rings.size(); ++h) s.area -= ringArea(s.rings[h]);
    json << (k ? "," : "") << R"({"type":"Feature","id":)" << k + 1
         << R"(,"properties":{},"geometry":{"type":"Polygon","coordinates":[)";
    for (std::size_t r = 0; r < s.rings.size(); ++r) {
      json << (r ? "," : "") << "[";
      for (std::size_t i = 0; i <= s.rings[r].size(); ++i) {
        const auto& p = s.rings[r][i % s.rings[r].size()];
        json << (i ? "," : "") << "[" << p[0] << "," << p[1] << "," << z(p[0], p[1]) << "]";
      }
      json << "]";
    }
    json << "]}}";
    shapes.push_back(std::move(s));
  }
  json << "]}";
  const MeshFile f = qota::loadMeshFile(writeText("stars.geojson", json.str()));
  ASSERT_EQ(f.format, "ogr:GeoJSON");

  std::vector<double> cut(shapes.size() + 1, 0.0);
  for (std::size_t p = 0; p < f.mesh.polygonCount(); ++p) {
    const auto idx = f.mesh.polygon(p);
    for (std::size_t i = 1; i + 1 < idx.size(); ++i) {
      const Eigen::Vector3d a = f.mesh.vertices[idx[0]], b = f.mesh.vertices[idx[i]], c = f.mesh.vertices[idx[i + 1]];
      cut[f.polygonSource[p]] += std::fabs((b - a).x() * (c - a).y() - (b - a).y() * (c - a).x()) / 2;
    }
  }
  for (std::size_t k = 0; k < shapes.size(); ++k) {
    EXPECT_NEAR(cut[k + 1], shapes[k].area, 1e-6 * shapes[k].area) << "seed " << seed << " polygon " << k + 1;
  }

  const CartesianIndex index(f.mesh, qota::CartesianMapping(Eigen::Vector3d(0, 0, -1), f.origin));
  std::uniform_real_distribution<double> offset(-12.0, 12.0);
  int checked = 0;
  for (std::size_t k = 0; k < shapes.size(); ++k) {
    const double cx = X0 + 30.0 * (k % 10), cy = Y0 + 30.0 * (k / 10);
    for (int i = 0; i < 40; ++i) {
      const double x = cx + (i % 2 ? offset(rng) : offset(rng) / 4), y = cy + offset(rng) / (i % 2 ? 1 : 4);
      bool in = insideRing(shapes[k].rings[0], x, y);
      double near = distanceToRing(shapes[k].rings[0], x, y);
      for (std::size_t h = 1; h < shapes[k].rings.size(); ++h) {
        in = in && !insideRing(shapes[k].rings[h], x, y);
        near = std::min(near, distanceToRing(shapes[k].rings[h], x, y));
      }
      if (near < 1e-6) continue;
      ++checked;
      const auto hit = index.top(x - f.origin.x(), y - f.origin.y());
      ASSERT_EQ(bool(hit), in) << "seed " << seed << " polygon " << k + 1 << " point " << i;
      if (hit) {
        EXPECT_NEAR(hit->height + f.origin.z(), z(x, y), 1e-6);
        EXPECT_EQ(f.polygonSource[hit->polygon], k + 1);
      }
    }
  }
  EXPECT_GT(checked, 3900);
}

}  // namespace

namespace {

TEST(MeshFileSafety, AssimpLoopingOnAFileIsAnError) {
  // A PLY header with a mangled end_header sends Debian's Assimp seeking for ever: the read runs
  // in a child process and is given up after the time limit, as an error naming the file.
  const auto path = std::filesystem::temp_directory_path() / "qota_tests" / "mangled.ply";
  std::filesystem::create_directories(path.parent_path());
  std::ofstream(path, std::ios::binary)
      << "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
         "element face 2\nproperty list uchar int vertex_indices\ne\xbd"
         "d_header\n0 0 1\n10 0 1\n10 10 2\n0 10 2\n4 0 1 2 3\n";
  qota::MeshFileOptions options;
  options.readerSeconds = 1;
  const auto start = std::chrono::steady_clock::now();
  try {
    qota::loadMeshFile(path.string(), options);
    FAIL() << "the mangled PLY was read";
  } catch (const qota::Error& e) {
    EXPECT_NE(std::string(e.what()).find("mangled.ply"), std::string::npos) << e.what();
  }
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(10));
}

TEST(MeshFileSafety, OgrLoopingOnADxfIsAnError) {
  // 157 bytes of DXF that send GDAL 3.6's DXF driver round for ever: read in a child process and
  // given up after the time limit.
  const auto path = std::filesystem::temp_directory_path() / "qota_tests" / "looping.dxf";
  std::filesystem::create_directories(path.parent_path());
  {
    std::ifstream crash(QOTA_SOURCE_DIR "/tests/fuzz/crashes/mesh/gdal_dxf_3dface_hang", std::ios::binary);
    crash.get();  // the harness's format byte
    std::ofstream(path, std::ios::binary) << crash.rdbuf();
  }
  qota::MeshFileOptions options;
  options.readerSeconds = 1;
  const auto start = std::chrono::steady_clock::now();
  try {
    qota::loadMeshFile(path.string(), options);
    FAIL() << "the looping DXF was read";
  } catch (const qota::Error& e) {
    EXPECT_NE(std::string(e.what()).find("looping.dxf"), std::string::npos) << e.what();
  }
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(10));
}

TEST(MeshFileSafety, HugeCoordinatesAreRefused) {
  const auto path = std::filesystem::temp_directory_path() / "qota_tests" / "huge.obj";
  std::ofstream(path) << "v 0 0 0\nv 1e308 0 0\nv 0 -1e308 0\nf 1 2 3\n";
  try {
    qota::loadMeshFile(path.string());
    FAIL() << "coordinates of 1e308 were accepted";
  } catch (const qota::Error& e) {
    EXPECT_NE(std::string(e.what()).find("beyond 1e100"), std::string::npos) << e.what();
  }
}

}  // namespace
