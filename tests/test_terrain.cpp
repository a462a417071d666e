// CartesianIndex against the brute-force oracle, and its query semantics and input rules.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <limits>
#include <random>
#include <type_traits>

#include "oracle.hpp"
#include "qota/error.hpp"
#include "qota/memory_budget.hpp"
#include "qota/terrain.hpp"
#include "random_terrain.hpp"

namespace {

using qota::CartesianIndex;
using qota::CartesianMapping;
using qota::Hit;
using qota::Mesh;
using qota::test::bruteForce;
constexpr double kInf = std::numeric_limits<double>::infinity();

// Compares every query kind at random world points with the oracle. Points within `ambiguous` of
// a polygon edge (where the answer depends on rounding) are counted, and their heights are
// checked only where the polygons' surfaces meet.
struct OracleStats {
  int queries = 0, ambiguous = 0, hits = 0;
};

// Void (gtest's ASSERT needs it); the counts go to `st`.
void compareWithOracle(const Mesh& mesh, const CartesianMapping& mapping, const qota::IndexOptions& options,
                       int queries, std::uint64_t seed, OracleStats& st) {
  const CartesianIndex index(mesh, mapping, options);
  Eigen::Vector3d lo = mesh.vertices[0], hi = mesh.vertices[0];
  for (const auto& v : mesh.vertices) lo = lo.cwiseMin(v), hi = hi.cwiseMax(v);
  const double size = (hi - lo).norm();
  const double ambiguous = 1e-9 * size;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(-0.1, 1.1);
  for (int q = 0; q < queries; ++q) {
    const Eigen::Vector3d p = lo + (hi - lo).cwiseProduct(Eigen::Vector3d(unit(rng), unit(rng), unit(rng)));
    const auto oracle = bruteForce(mesh, mapping.gravity(), mapping.origin(), p);
    ++st.queries;
    if (oracle.nearestEdge < ambiguous) {
      ++st.ambiguous;
      continue;
    }
    const double z = mapping.toMapped(p).z();
    // Oracle answers: topmost, nearest below z, nearest above z (ties: smallest polygon id).
    const qota::test::OracleHit *top = nullptr, *below = nullptr, *above = nullptr;
    bool heightTie = false;
    for (const auto& h : oracle.hits) {
      auto better = [&](const qota::test::OracleHit* cur, bool higher) {
        if (!cur) return true;
        if (h.height == cur->height) return h.polygon < cur->polygon;
        return higher ? h.height > cur->height : h.height < cur->height;
      };
      if (std::fabs(h.height - z) < ambiguous) heightTie = true;
      if (better(top, true)) top = &h;
      if (h.height <= z && better(below, true)) below = &h;
      if (h.height >= z && better(above, false)) above = &h;
    }
    for (const auto& h1 : oracle.hits) {
      for (const auto& h2 : oracle.hits) {
        if (h1.polygon != h2.polygon && std::fabs(h1.height - h2.height) < ambiguous) heightTie = true;
      }
    }
    if (heightTie) {
      ++st.ambiguous;
      continue;
    }
    auto check = [&](const std::optional<Hit>& got, const qota::test::OracleHit* want, const char* what) {
      ASSERT_EQ(got.has_value(), want != nullptr) << what << " at query " << q;
      if (!want) return;
      ASSERT_EQ(got->polygon, want->polygon) << what << " at query " << q;
      ASSERT_NEAR(got->height, want->height, 1e-9 * std::max(1.0, std::fabs(want->height)))
          << what << " at query " << q;
      // The world point lies on the line and at that height.
      const Eigen::Vector3d m = mapping.toMapped(got->world);
      const Eigen::Vector3d pm = mapping.toMapped(p);
      ASSERT_NEAR(m.x(), pm.x(), 1e-9 * size);
      ASSERT_NEAR(m.y(), pm.y(), 1e-9 * size);
      ASSERT_NEAR(got->normal.norm(), 1.0, 1e-12);
      ASSERT_LT(got->normal.dot(mapping.gravity()), 0.0);  // points up
    };
    check(index.topWorld(p), top, "top");
    check(index.belowWorld(p), below, "below");
    check(index.aboveWorld(p), above, "above");
    const auto br = index.bracketWorld(p);
    check(br.below, below, "bracket.below");
    check(br.above, above, "bracket.above");
    const auto all = index.allWorld(p);
    ASSERT_EQ(all.size(), oracle.hits.size()) << "all at query " << q;
    for (std::size_t i = 1; i < all.size(); ++i) ASSERT_GE(all[i - 1].height, all[i].height);
    for (const auto& h : oracle.hits) {
      ASSERT_TRUE(std::any_of(all.begin(), all.end(), [&](const Hit& g) { return g.polygon == h.polygon; }));
    }
    if (top) ++st.hits;
  }
}

OracleStats compareWithOracle(const Mesh& mesh, const CartesianMapping& mapping, const qota::IndexOptions& options,
                              int queries, std::uint64_t seed) {
  OracleStats st;
  compareWithOracle(mesh, mapping, options, queries, seed, st);
  return st;
}

TEST(TerrainOracle, VerticalGravity) {
  for (std::uint64_t seed = 1; seed <= 4; ++seed) {
    const Mesh mesh = qota::test::randomTerrain({}, seed);
    const auto st = compareWithOracle(mesh, CartesianMapping(), {}, 4000, seed);
    EXPECT_GT(st.hits, st.queries / 4);
    EXPECT_LT(st.ambiguous, st.queries / 100);
  }
}

TEST(TerrainOracle, TiltedGravity) {
  std::mt19937_64 rng(77);
  std::normal_distribution<double> n(0, 1);
  for (std::uint64_t seed = 10; seed < 16; ++seed) {
    Eigen::Vector3d g(n(rng), n(rng), n(rng));
    if (seed == 15) g = Eigen::Vector3d(1, 0.3, 0);  // sideways: a wall-like view of the terrain
    const Mesh mesh = qota::test::randomTerrain({}, seed);
    const auto st = compareWithOracle(mesh, CartesianMapping(g, Eigen::Vector3d(3, 4, 5)), {}, 3000, seed);
    EXPECT_GT(st.hits, 0);
    EXPECT_LT(st.ambiguous, st.queries / 100);
  }
}

TEST(TerrainOracle, TreeParametersDoNotChangeAnswers) {
  const Mesh mesh = qota::test::randomTerrain({}, 21);
  for (const qota::QuadtreeOptions tree : {qota::QuadtreeOptions{2, 12}, qota::QuadtreeOptions{400, 5},
                                           qota::QuadtreeOptions{3, 2}, qota::QuadtreeOptions{8, 0}}) {
    compareWithOracle(mesh, CartesianMapping(Eigen::Vector3d(0.2, -0.1, -1)), {tree}, 1500, 21);
  }
}

TEST(TerrainOracle, LargeCoordinates) {
  // A terrain in map coordinates in the millions (UTM-like), origin near the data.
  qota::test::RandomTerrainSpec spec;
  spec.offsetX = 557805;
  spec.offsetY = 5122005;
  spec.cell = 30;
  const Mesh mesh = qota::test::randomTerrain(spec, 5);
  compareWithOracle(mesh, CartesianMapping(Eigen::Vector3d(0, 0, -1), Eigen::Vector3d(558000, 5122400, 0)), {}, 3000,
                    5);
  compareWithOracle(mesh, CartesianMapping(Eigen::Vector3d(0.1, 0, -1), Eigen::Vector3d(558000, 5122400, 0)), {}, 3000,
                    6);
}

TEST(TerrainOracle, TinyAndHugeTriangles) {
  // The triangle records keep corners 1 and 2 relative to corner 0 in float: at 1e-39 and 1e31
  // (beyond a normal float) every edge test goes to the exact predicate; at 1e-30 and 1e25 the
  // float path and its error bound work far from unit scale.
  for (const double cell : {1e-39, 1e-30, 1e25, 1e31}) {
    qota::test::RandomTerrainSpec spec;
    spec.cell = cell;
    spec.offsetX = 7 * cell, spec.offsetY = -3 * cell;
    spec.walls = 0;  // their size is absolute
    const Mesh mesh = qota::test::randomTerrain(spec, 31);
    SCOPED_TRACE(cell);
    OracleStats st;
    compareWithOracle(mesh, CartesianMapping(Eigen::Vector3d(0.1, 0.2, -1)), {}, 1500, 31, st);
    EXPECT_GT(st.hits, st.queries / 4);
    EXPECT_LT(st.ambiguous, st.queries / 100);
  }
}

// --- Semantics -------------------------------------------------------------------------------

Mesh twoFloors() {
  // A unit square floor at h = 0 (two triangles) and a ceiling quad at h = 3 (one polygon).
  Mesh m;
  for (double z : {0.0, 3.0}) {
    m.addVertex({0, 0, z});
    m.addVertex({1, 0, z});
    m.addVertex({1, 1, z});
    m.addVertex({0, 1, z});
  }
  m.addTriangle(0, 1, 2);
  m.addTriangle(0, 2, 3);
  m.addPolygon({4, 5, 6, 7});
  return m;
}

TEST(TerrainQueries, FloorAndCeiling) {
  const CartesianIndex index(twoFloors(), CartesianMapping());
  const auto b = index.bracket(0.3, 0.6, 1.0);
  ASSERT_TRUE(b.below && b.above);
  EXPECT_EQ(b.below->height, 0.0);
  EXPECT_EQ(b.below->polygon, 1u);  // (0.3, 0.6) is in the second triangle
  EXPECT_EQ(b.above->height, 3.0);
  EXPECT_EQ(b.above->polygon, 2u);
  EXPECT_EQ(index.top(0.3, 0.6)->height, 3.0);
  EXPECT_FALSE(index.below(0.3, 0.6, -0.5));
  EXPECT_FALSE(index.above(0.3, 0.6, 3.5));
  // Exactly at a surface: both below and above.
  EXPECT_EQ(index.below(0.5, 0.5, 3.0)->height, 3.0);
  EXPECT_EQ(index.above(0.5, 0.5, 3.0)->height, 3.0);
  // On the shared diagonal: the smaller polygon id wins the tie.
  EXPECT_EQ(index.below(0.5, 0.5, 1.0)->polygon, 0u);
  const auto all = index.all(0.5, 0.5);
  ASSERT_EQ(all.size(), 3u);  // the ceiling once, both floor triangles
  EXPECT_EQ(all[0].height, 3.0);
  EXPECT_EQ(all[0].polygon, 2u);
  // Outside the terrain, NaN: no terrain, not an error.
  EXPECT_FALSE(index.top(1.5, 0.5));
  EXPECT_FALSE(index.top(NAN, 0.5));
  EXPECT_TRUE(index.all(-1, -1).empty());
}

TEST(TerrainQueries, NormalAndWorldPoint) {
  // A plane z = 0.5 x tilted about y.
  Mesh m;
  m.addVertex({0, 0, 0});
  m.addVertex({2, 0, 1});
  m.addVertex({0, 2, 0});
  m.addTriangle(0, 1, 2);
  const CartesianIndex index(m, CartesianMapping());
  const auto h = index.top(0.5, 0.5);
  ASSERT_TRUE(h);
  EXPECT_DOUBLE_EQ(h->height, 0.25);
  EXPECT_TRUE(h->world.isApprox(Eigen::Vector3d(0.5, 0.5, 0.25)));
  EXPECT_TRUE(h->normal.isApprox(Eigen::Vector3d(-0.5, 0, 1).normalized()));
}

TEST(TerrainQueries, EmptyTerrain) {
  const CartesianIndex index(Mesh{}, CartesianMapping());
  EXPECT_FALSE(index.top(0, 0));
  EXPECT_EQ(index.stats().triangles, 0u);
  EXPECT_EQ(index.stats().tree.nodes, 1u);
}

TEST(TerrainQueries, FanAroundAVertexDeeperThanMaxPoly) {
  // 64 triangles around one vertex: no split can separate them; Maxdepth (and the size floor,
  // half a triangle) stop the tree.
  Mesh m;
  const std::uint32_t c = m.addVertex({0.3, 0.2, 1});
  const int n = 64;
  for (int i = 0; i < n; ++i) {
    const double a = 2 * M_PI * i / n;
    m.addVertex({0.3 + std::cos(a), 0.2 + std::sin(a), 0});
  }
  for (int i = 0; i < n; ++i) m.addTriangle(c, 1 + i, 1 + (i + 1) % n);
  const CartesianIndex index(m, CartesianMapping(), {{4, 10}});
  EXPECT_LE(index.stats().tree.depth, 10u);
  EXPECT_GE(index.stats().tree.depth, 1u);
  const auto h = index.top(0.3, 0.2);
  ASSERT_TRUE(h);
  EXPECT_EQ(h->height, 1.0);
  EXPECT_EQ(h->polygon, 0u);
  // A fan centred on the root's centre meets all four children: nothing to split.
  for (auto& v : m.vertices) v -= Eigen::Vector3d(0.3, 0.2, 0);
  const CartesianIndex centred(m, CartesianMapping(), {{4, 10}});
  EXPECT_EQ(centred.stats().tree.depth, 0u);
  EXPECT_EQ(centred.top(0, 0)->height, 1.0);
}

// An nx x ny lattice of cells dx by dy, two triangles a cell, heights z(i, j) at its vertices.
template <class Height>
Mesh lattice(int nx, int ny, double dx, double dy, Height&& z) {
  Mesh m;
  for (int j = 0; j <= ny; ++j) {
    for (int i = 0; i <= nx; ++i) m.addVertex({dx * i, dy * j, z(i, j)});
  }
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) {
      const auto a = static_cast<std::uint32_t>(j * (nx + 1) + i), n = static_cast<std::uint32_t>(nx);
      m.addTriangle(a, a + 1, a + n + 2);
      m.addTriangle(a, a + n + 2, a + n + 1);
    }
  }
  return m;
}

TEST(TerrainQueries, SliversFarThinnerThanTheirNodeStayALeaf) {
  // A 16 x 16 lattice a millionth wide and 16 tall (a raster with an absurd geotransform): the
  // root is widened to a square, so no cut below the first parts the columns, and every cut
  // across the rows copies a row's 32 slivers into both halves. Counting the empty children as
  // free queries, the split rule used to take that for a gain and split down to Maxdepth (half a
  // million nodes, two million references, seconds to build). Now the rows stay leaves, and the
  // answers are still the oracle's.
  const Mesh m = lattice(16, 16, 1e-6, 1, [](int i, int j) { return double((i * 5 + j * 3) % 7); });
  const qota::IndexOptions options{.tree = {8, 16}, .gridFastPath = false};
  const CartesianIndex index(m, CartesianMapping(), options);
  EXPECT_LT(index.stats().tree.references, 32u * index.stats().triangles);
  EXPECT_LT(index.stats().tree.nodes, 8u * index.stats().triangles);
  const auto st = compareWithOracle(m, CartesianMapping(), options, 3000, 9);
  EXPECT_GT(st.hits, st.queries / 2);
}

TEST(TerrainQueries, ATreeOutgrowingTheMemoryLeftStopsWithAnError) {
  // Slivers 100 times taller than wide (a 2600 x 13 raster of the whole globe): the square cells
  // that part their columns cut each of them many times, some 20 nodes a triangle, more than the
  // up-front estimate. With memory for the estimate but not for such a tree, the build stops
  // with an error instead of meeting the OOM killer.
  const Mesh m = lattice(2600, 13, 360.0 / 2600, 180.0 / 13, [](int i, int j) { return double((i * 7 + j * 3) % 11); });
  const qota::IndexOptions options{.tree = {8, 16}, .gridFastPath = false};
  const CartesianIndex unlimited(m, CartesianMapping(), options);
  ASSERT_GT(unlimited.stats().tree.nodes, 1u << 20);  // the tree the check must see
  qota::memory::setLimit(qota::memory::peakBytes() + (48ull << 20));
  try {
    const CartesianIndex limited(m, CartesianMapping(), options);
    qota::memory::setLimit(0);
    FAIL() << "built " << limited.stats().tree.nodes << " nodes";
  } catch (const qota::Error& e) {
    qota::memory::setLimit(0);
    const std::string what = e.what();
    EXPECT_NE(what.find("of memory"), std::string::npos) << what;
    EXPECT_NE(what.find("raise Maxpoly or lower Maxdepth"), std::string::npos) << what;
  }
}

// --- Input rules -----------------------------------------------------------------------------

// Walks through a cursor over a tree larger than a cache holds, where the cursor fetches the
// leaves ahead of a walk: straight runs of small steps (the course it predicts), turns, reversals,
// steps as large as a leaf, jumps, points off the terrain, over a heightfield with holes and
// overlapping plates. Every answer is the plain query's; the oracle checks the plain answers at
// some of the points.
TEST(TerrainQueries, LongCursorWalksOverALargeTreeAnswerAsPlainQueries) {
  const Mesh mesh = qota::test::randomTerrain({.grid = 400, .plates = 12, .walls = 5}, 23);
  const CartesianIndex index(mesh, CartesianMapping());
  ASSERT_FALSE(index.gridFastPath());
  ASSERT_GT(index.stats().tree.memoryBytes, std::uint64_t{8} << 20) << "too small a tree to fetch ahead";
  std::mt19937_64 rng(29);
  std::uniform_real_distribution<double> unit(0, 1);
  qota::Cursor cursor;
  double u = 20, v = 30, du = 0.02, dv = 0.007;
  int checked = 0;
  for (int i = 0; i < 150000; ++i) {
    if (i % 4000 == 0) {  // a new course: steps from a thousandth of a cell to half a dozen cells
      const double length = std::pow(10.0, -3 + 3.8 * unit(rng)), angle = 2 * std::numbers::pi * unit(rng);
      du = length * std::cos(angle), dv = length * std::sin(angle);
    }
    if (i % 4000 == 2000) du = -du, dv = -dv;  // back the way it came
    if (i % 500 == 250) {                      // a gentle turn
      const double a = 0.05 * (unit(rng) - 0.5), c = std::cos(a), s = std::sin(a);
      const double ru = c * du - s * dv, rv = s * du + c * dv;
      du = ru, dv = rv;
    }
    if (i % 9973 == 0) u = 400 * unit(rng), v = 400 * unit(rng);  // a jump
    u += du, v += dv;
    if (u < -3 || u > 402) du = -du;  // (a little off the terrain, then back)
    if (v < -3 || v > 402) dv = -dv;
    const double z = i % 3 == 0 ? kInf : 160 * (unit(rng) - 0.5);
    ASSERT_EQ(index.heightBelow(cursor, u, v, z), index.heightBelow(u, v, z))
        << "step " << i << " at " << u << " " << v;
    if (i % 7 == 0) {
      const auto a = index.above(cursor, u, v, z), b = index.above(u, v, z);
      ASSERT_EQ(a.has_value(), b.has_value()) << "step " << i;
      if (a) {
        ASSERT_EQ(a->polygon, b->polygon) << "step " << i;
      }
    }
    if (i % 1500 == 0) {
      const auto oracle = bruteForce(mesh, CartesianMapping().gravity(), CartesianMapping().origin(), {u, v, 0.0});
      if (oracle.nearestEdge < 1e-9) continue;
      std::optional<double> want;
      for (const auto& h : oracle.hits) {
        if (h.height <= z && (!want || h.height > *want)) want = h.height;
      }
      const auto got = index.heightBelow(cursor, u, v, z);
      ASSERT_EQ(got.has_value(), want.has_value()) << "step " << i;
      if (want) {
        ASSERT_NEAR(*got, *want, 1e-9 * std::max(1.0, std::fabs(*want))) << "step " << i;
      }
      ++checked;
    }
  }
  EXPECT_GT(checked, 80);
}

TEST(TerrainQueries, ParallelBuildIsTheSerialBuild) {
  // The build's parts split by triangle and by leaf on two threads make the same index, node for
  // node and reference for reference, as one thread; so the same answers.
  const Mesh mesh = qota::test::randomTerrain({.grid = 200, .plates = 300, .walls = 20}, 17);
  qota::IndexOptions one, two;
  one.buildThreads = 1, two.buildThreads = 2;
  const CartesianIndex serial(mesh, CartesianMapping(), one), parallel(mesh, CartesianMapping(), two);
  ASSERT_FALSE(serial.gridFastPath());
  const auto a = serial.tree().nodes(), b = parallel.tree().nodes();
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    ASSERT_EQ(a[i].first, b[i].first) << i;
    ASSERT_EQ(a[i].count, b[i].count) << i;
  }
  const auto ra = serial.tree().references(), rb = parallel.tree().references();
  ASSERT_TRUE(std::equal(ra.begin(), ra.end(), rb.begin(), rb.end()));
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> at(-1, 200);
  for (int k = 0; k < 20000; ++k) {
    const double u = at(rng), v = at(rng);
    const auto hs = serial.heightBelow(u, v, 30), hp = parallel.heightBelow(u, v, 30);
    ASSERT_EQ(hs, hp) << u << " " << v;
  }
}

TEST(TerrainInput, WallsAreLeftOutAndCounted) {
  Mesh m = twoFloors();
  const auto a = m.addVertex({0, 0, 0}), b = m.addVertex({1, 0, 0}), c = m.addVertex({1, 0, 2}),
             d = m.addVertex({0, 0, 2});
  m.addPolygon({a, b, c, d});
  m.addTriangle(a, a, b);  // degenerate
  const CartesianIndex index(m, CartesianMapping());
  EXPECT_EQ(index.stats().leftOut, 2u);
  EXPECT_EQ(index.stats().polygons, 5u);
  EXPECT_EQ(index.stats().triangles, 4u);
}

TEST(TerrainInput, ErrorsNameThePolygon) {
  auto expectError = [](const Mesh& m, const std::string& needle) {
    try {
      CartesianIndex index(m, CartesianMapping());
      FAIL() << "no error, expected one mentioning '" << needle << "'";
    } catch (const qota::Error& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  Mesh nan = twoFloors();
  nan.vertices[6].y() = NAN;
  expectError(nan, "polygon 2");
  Mesh range = twoFloors();
  range.addTriangle(0, 1, 99);
  expectError(range, "polygon 3 refers to vertex 99");
  Mesh nonConvex;
  for (auto [x, y] : {std::pair{0.0, 0.0}, {2.0, 0.0}, {1.0, 0.5}, {2.0, 2.0}, {0.0, 2.0}}) {
    nonConvex.addVertex({x, y, 0});
  }
  nonConvex.addPolygon({0, 1, 2, 3, 4});
  expectError(nonConvex, "polygon 0 (5 vertices) is not convex");
  Mesh bowtie;
  for (auto [x, y] : {std::pair{0.0, 0.0}, {1.0, 0.0}, {0.0, 1.0}, {1.0, 1.0}}) bowtie.addVertex({x, y, 0});
  bowtie.addPolygon({0, 1, 2, 3});
  expectError(bowtie, "not convex");
  Mesh two;
  two.addVertex({0, 0, 0});
  two.addVertex({1, 0, 0});
  two.offsets = {0, 2};
  two.indices = {0, 1};
  expectError(two, "polygon 0 has 2 vertices");
}

}  // namespace

// Batches against single queries: IndexFace.BatchesAnswerAsSingleQueriesBitForBit
// (test_index_typed.cpp), for this index and every other.

// The names of 0.1 still name the same types for one release (deprecated in 0.2).
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wdeprecated-declarations"
static_assert(std::is_same_v<qota::TerrainOptions, qota::IndexOptions>);
static_assert(std::is_same_v<qota::TerrainStats, qota::IndexStats>);
static_assert(std::is_same_v<qota::CurvedStats, qota::IndexStats>);
#pragma GCC diagnostic pop
