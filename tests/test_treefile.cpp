// Tree files: every kind of index round-trips with identical answers; truncated, altered and
// foreign files are clear errors.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <random>
#include <unistd.h>

#include "qota/error.hpp"
#include "qota/globe.hpp"
#include "qota/mesh_io.hpp"
#include "qota/synthetic.hpp"
#include "qota/treefile.hpp"
#include "oracle.hpp"
#include "random_terrain.hpp"
#include "raster_files.hpp"

namespace {

using namespace qota;
namespace fs = std::filesystem;

fs::path tempPath(const std::string& name) {
  return fs::temp_directory_path() / ("qota_test_" + std::to_string(::getpid()) + "_" + name);
}

std::vector<char> readAll(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}
void writeAll(const fs::path& p, const std::vector<char>& bytes) {
  std::ofstream(p, std::ios::binary).write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

template <class Index, class Query>
void expectRoundTrip(const Index& index, const std::string& name, Query&& query) {
  const fs::path path = tempPath(name);
  TreeSource source;
  source.path = "from/" + name;
  source.width = 7;
  saveTree(path.string(), index, source);
  const TreeFile loaded = loadTree(path.string());
  fs::remove(path);
  ASSERT_TRUE(std::holds_alternative<Index>(loaded.index));
  EXPECT_EQ(loaded.source.path, source.path);
  EXPECT_EQ(loaded.source.width, 7);
  const Index& back = std::get<Index>(loaded.index);
  EXPECT_EQ(back.mapping().describe(), index.mapping().describe());
  EXPECT_EQ(back.stats().tree.nodes, index.stats().tree.nodes);
  std::mt19937_64 rng(9);
  for (int i = 0; i < 20000; ++i) {
    const auto [a, b] = query(index, back, rng);
    ASSERT_EQ(a.has_value(), b.has_value()) << i;
    if (a) {
      ASSERT_EQ(a->height, b->height);
      ASSERT_EQ(a->polygon, b->polygon);
    }
  }
}

double uniform(std::mt19937_64& rng, double lo, double hi) {
  return std::uniform_real_distribution<double>(lo, hi)(rng);
}

TEST(TreeFile, EveryKindRoundTrips) {
  test::RandomTerrainSpec spec;
  spec.grid = 60;
  spec.offsetX = 5e5, spec.offsetY = 5e6;  // map coordinates
  const Mesh mesh = test::randomTerrain(spec, 3);
  const CartesianMapping cart(Eigen::Vector3d(0.1, 0, -1), Eigen::Vector3d(5e5, 5e6, 0));
  const CartesianIndex flat(mesh, cart);
  expectRoundTrip(flat, "flat.qota", [](const auto& a, const auto& b, std::mt19937_64& rng) {
    const double u = uniform(rng, -40, 40), v = uniform(rng, -40, 40), h = uniform(rng, -20, 20);
    return std::pair(a.below(u, v, h), b.below(u, v, h));
  });
  const PlanetTerrain planet = loadPlanet(QOTA_DATA_DIR "/etopo20.tif");
  const SphericalIndex sphere(planet.dem.mesh, planet.mapping);
  expectRoundTrip(sphere, "sphere.qota", [](const auto& a, const auto& b, std::mt19937_64& rng) {
    const double u = uniform(rng, -180, 180), v = uniform(rng, -90, 90);
    return std::pair(a.top(u, v), b.top(u, v));
  });
  const Mesh station = stationMesh(fractalHeightfield(90, 30, 1.0, 5.0, 2), {200, 500});
  const CylindricalIndex tube(station, CylindricalMapping({1, 2, 3}, {0, 1, 0}));
  expectRoundTrip(tube, "tube.qota", [](const auto& a, const auto& b, std::mt19937_64& rng) {
    const double u = uniform(rng, -180, 180), v = uniform(rng, -240, 240);
    return std::pair(a.top(u, v), b.top(u, v));
  });
  // The summit's 300 x 300 pixels (-121.89 to -121.64, 46.73 to 46.98): real heights and a geoid,
  // a sixteenth of the tile's build.
  const auto summit = test::scratchPath("treefile_summit_" + std::to_string(::getpid()) + ".tif");
  test::cropRaster(QOTA_DATA_DIR "/mt_rainier_90m.tif", summit, 138, 27, 300, 300);
  const EllipsoidTerrain srtm = loadOnEllipsoid(summit.string());
  fs::remove(summit);
  const GeodeticIndex earth(srtm.dem.mesh, srtm.mapping);
  expectRoundTrip(earth, "earth.qota", [](const auto& a, const auto& b, std::mt19937_64& rng) {
    const double u = uniform(rng, -121.90, -121.62), v = uniform(rng, 46.72, 46.99);
    return std::pair(a.top(u, v), b.top(u, v));
  });
  const EnuIndex local(srtm.dem.mesh, EnuMapping(46.85, -121.76, 1500.0));
  expectRoundTrip(local, "local.qota", [](const auto& a, const auto& b, std::mt19937_64& rng) {
    const double u = uniform(rng, -1.2e4, 1.2e4), v = uniform(rng, -1.6e4, 1.6e4), h = uniform(rng, -1e3, 3e3);
    return std::pair(a.below(u, v, h), b.below(u, v, h));
  });
}

// A version 4 file (128-byte triangle records), written by qota 0.3 before the records became 64
// bytes, from tests/data/old_tree_mesh.obj (a jittered TIN in map coordinates with a bridge of
// quads above it): it loads, its records remade from its corners, and answers as the mesh built
// today does, bit for bit, and as the brute-force oracle does away from edges.
TEST(TreeFile, VersionFourFilesAreConverted) {
  const TreeFile old = loadTree(QOTA_SOURCE_DIR "/tests/data/old_tree_v4.qota");
  ASSERT_TRUE(std::holds_alternative<CartesianIndex>(old.index));
  const CartesianIndex& back = std::get<CartesianIndex>(old.index);
  const MeshFile file = loadMeshFile(QOTA_SOURCE_DIR "/tests/data/old_tree_mesh.obj");
  const CartesianIndex fresh(file.mesh, back.mapping());
  EXPECT_EQ(back.stats().triangles, fresh.stats().triangles);
  std::mt19937_64 rng(4);
  int hits = 0, checked = 0, twoLayers = 0;
  for (int i = 0; i < 20000; ++i) {
    // The TIN spans (500000, 4000000) to (500130, 4000130) in the world: the mapping's frame is
    // found from the world point, as a user's query is.
    const Eigen::Vector3d world(uniform(rng, 499990, 500140), uniform(rng, 3999990, 4000140), uniform(rng, 60, 200));
    const auto a = back.belowWorld(world), b = fresh.belowWorld(world);
    ASSERT_EQ(a.has_value(), b.has_value()) << i;
    if (!a) continue;
    ++hits;
    ASSERT_EQ(a->height, b->height) << i;
    ASSERT_EQ(a->polygon, b->polygon) << i;
    const test::OracleResult o = test::bruteForce(file.mesh, back.mapping().gravity(), back.mapping().origin(), world);
    if (o.nearestEdge < 1e-6) continue;
    // The highest crossing at or below the point's own height.
    const double z = -back.mapping().gravity().dot(world - back.mapping().origin());
    const test::OracleHit* best = nullptr;
    for (const auto& h : o.hits) {
      if (h.height <= z && (!best || h.height > best->height)) best = &h;
    }
    twoLayers += o.hits.size() > 1;
    ASSERT_TRUE(best) << i;
    EXPECT_NEAR(a->height, best->height, 1e-9) << i;
    EXPECT_EQ(a->polygon, best->polygon) << i;
    ++checked;
  }
  EXPECT_GT(hits, 10000);
  EXPECT_GT(checked, 10000);
  EXPECT_GT(twoLayers, 100);  // the bridge's overlaps were met
}

TEST(TreeFile, DamagedFilesAreClearErrors) {
  const Mesh mesh = fractalHeightfield(40, 40, 1.0, 5.0, 4).toMesh();
  const CartesianIndex index(mesh, CartesianMapping());
  const fs::path good = tempPath("good.qota"), bad = tempPath("bad.qota");
  saveTree(good.string(), index);
  ASSERT_TRUE(isTreeFile(good.string()));
  const std::vector<char> bytes = readAll(good);
  auto expectError = [&](const std::vector<char>& b, const std::string& fragment) {
    writeAll(bad, b);
    try {
      loadTree(bad.string());
      ADD_FAILURE() << "loaded a damaged file (" << fragment << ")";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(bad.string()), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
    }
  };
  // Truncated anywhere.
  for (std::size_t n :
       {std::size_t{0}, std::size_t{5}, std::size_t{20}, std::size_t{40}, bytes.size() / 2, bytes.size() - 1}) {
    expectError(std::vector<char>(bytes.begin(), bytes.begin() + n), n < 8    ? "not a qota tree file"
                                                                     : n < 32 ? "truncated"
                                                                              : "truncated");
  }
  // One byte changed anywhere in the payload: the checksum (or an earlier structural check).
  std::mt19937_64 rng(5);
  for (int i = 0; i < 50; ++i) {
    std::vector<char> b = bytes;
    const std::size_t at = 32 + rng() % (b.size() - 32);
    b[at] = static_cast<char>(b[at] ^ (1 << (rng() % 8)));
    writeAll(bad, b);
    EXPECT_THROW(loadTree(bad.string()), Error) << "byte " << at;
  }
  std::vector<char> b = bytes;
  b[8] = 9;  // version
  expectError(b, "version 9");
  b = bytes;
  b.push_back('x');
  expectError(b, "truncated or extended");
  expectError(std::vector<char>{'h', 'e', 'l', 'l', 'o', ' ', 'w', 'o', 'r', 'l', 'd'}, "not a qota tree file");
  EXPECT_THROW(loadTree("/no/such/tree.qota"), Error);
  EXPECT_FALSE(isTreeFile(QOTA_DATA_DIR "/mt_rainier_90m.tif"));
  // An unwritable destination leaves nothing behind.
  EXPECT_THROW(saveTree("/no/such/dir/t.qota", index), Error);
  fs::remove(good);
  fs::remove(bad);
}

}  // namespace
