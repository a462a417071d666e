// The grid fast path answers exactly as the quadtree: on the real DEM, a rotated grid and a
// synthetic one, at random points, exactly at vertices, on edges and on cut lines; it turns
// itself off for meshes that are not grids and after insertions.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <atomic>
#include <random>
#include <span>
#include <thread>

#include "qota/dem.hpp"
#include "qota/synthetic.hpp"
#include "qota/terrain.hpp"

namespace {

using namespace qota;

double uniform(std::mt19937_64& rng, double lo, double hi) {
  return std::uniform_real_distribution<double>(lo, hi)(rng);
}

IndexOptions quadtreeOnly() {
  IndexOptions o;
  o.gridFastPath = false;
  return o;
}

// Every query kind at the point, both ways.
void expectSame(const TerrainIndex& fast, const TerrainIndex& slow, double u, double v, double z) {
  const auto a = fast.below(u, v, z), b = slow.below(u, v, z);
  ASSERT_EQ(a.has_value(), b.has_value()) << u << " " << v << " " << z;
  if (a) {
    ASSERT_EQ(a->height, b->height) << u << " " << v;
    ASSERT_EQ(a->polygon, b->polygon) << u << " " << v;
  }
  const auto c = fast.above(u, v, z), d = slow.above(u, v, z);
  ASSERT_EQ(c.has_value(), d.has_value());
  if (c) {
    ASSERT_EQ(c->polygon, d->polygon);
  }
  ASSERT_EQ(fast.heightBelow(u, v, 1e300), slow.heightBelow(u, v, 1e300));
}

void expectGridMatchesQuadtree(const Mesh& mesh, const CartesianMapping& mapping, int randomQueries,
                               std::uint64_t seed) {
  const TerrainIndex fast(mesh, mapping), slow(mesh, mapping, quadtreeOnly());
  ASSERT_TRUE(fast.gridFastPath());
  ASSERT_FALSE(slow.gridFastPath());
  // No triangle records until something needs the tree: under Embree's 80 bytes a triangle.
  const std::uint64_t leanBytes = fast.memoryBytesNow();
  EXPECT_LT(leanBytes, 40 * fast.stats().triangles);
  const Box2 box = fast.stats().domain;
  std::mt19937_64 rng(seed);
  std::vector<Point2> points;
  for (int i = 0; i < randomQueries; ++i) {
    points.push_back({uniform(rng, box.ulo - 1e-3 * (box.uhi - box.ulo), box.uhi),
                      uniform(rng, box.vlo, box.vhi + 1e-3 * (box.vhi - box.vlo))});
  }
  // Adversarial: exactly at vertices, along edges (rounded on either side), on the quadtree's
  // cut lines.
  for (int i = 0; i < randomQueries / 4; ++i) {
    const auto p = mesh.polygon(rng() % mesh.polygonCount());
    const Eigen::Vector3d a = mapping.toMapped(mesh.vertices[p[0]]), b = mapping.toMapped(mesh.vertices[p[1]]);
    points.push_back({a.x(), a.y()});
    const double s = uniform(rng, 0, 1);
    points.push_back({a.x() + s * (b.x() - a.x()), a.y() + s * (b.y() - a.y())});
    points.push_back({0.5 * (box.ulo + box.uhi), uniform(rng, box.vlo, box.vhi)});
  }
  for (const Point2& p : points) {
    const double z = uniform(rng, -1e4, 1e4);
    expectSame(fast, slow, p.u, p.v, z);
    if (::testing::Test::HasFatalFailure()) return;
  }
  std::vector<std::optional<double>> a(points.size()), b(points.size());
  fast.heightsBelow(points, 1e300, a);
  slow.heightsBelow(points, 1e300, b);
  std::vector<std::optional<double>> d(points.size());
  fast.heightsBelowParallel(points, 1e300, d, 2);
  ASSERT_EQ(d, a);
  slow.heightsBelowParallel(points, 1e300, d, 2);
  ASSERT_EQ(d, b);
  for (std::size_t i = 0; i < points.size(); ++i) {
    ASSERT_EQ(a[i], b[i]) << i;
  }
  // Queries on the grid, single, batched or parallel, never build the tree (stats() does).
  // (A sample of the points: the sanitizer builds run this too.)
  const TerrainIndex lean(mesh, mapping);
  const std::uint64_t before = lean.memoryBytesNow();
  const std::size_t m = std::min<std::size_t>(points.size(), 20000);
  const std::span<const Point2> some(points.data(), m);
  std::vector<std::optional<double>> e(m);
  lean.heightsBelowParallel(some, 1e300, e, 2);
  ASSERT_TRUE(std::equal(e.begin(), e.end(), a.begin()));
  const std::vector<double> zs(m, 1e300);
  lean.heightsBelowParallel(some, zs, e, 2);
  ASSERT_TRUE(std::equal(e.begin(), e.end(), a.begin()));
  lean.heightsBelow(some, 1e300, e);
  for (std::size_t i = 0; i < m; i += 97) {
    (void)lean.below(points[i].u, points[i].v, 0.0), (void)lean.above(points[i].u, points[i].v, 0.0);
  }
  EXPECT_EQ(lean.memoryBytesNow(), before) << "a query on the grid built the quadtree";
}

TEST(GridFastPath, RainierMatchesTheQuadtree) {
  const DemTerrain dem = loadDem(QOTA_DATA_DIR "/mt_rainier_90m.tif", {.lonLatAsCartesian = true});  // with nodata holes
  expectGridMatchesQuadtree(dem.mesh, dem.mapping, 400000, 1);
}

TEST(GridFastPath, RotatedAndSyntheticGrids) {
  Heightfield f = fractalHeightfield(120, 90, 2.5, 30.0, 3);
  f.x0 = 3e5, f.y0 = 5e6;
  Mesh mesh = f.toMesh();
  expectGridMatchesQuadtree(mesh, CartesianMapping({0, 0, -1}, {3e5, 5e6, 0}), 100000, 2);
  // Rotated by 30 degrees about the vertical: still an affine grid.
  const Eigen::Matrix3d r = Eigen::AngleAxisd(0.52, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  for (auto& v : mesh.vertices) v = r * (v - Eigen::Vector3d(3e5, 5e6, 0));
  expectGridMatchesQuadtree(mesh, CartesianMapping(), 100000, 3);
  // Under a tilted gravity the heights shift the projected vertices off the grid: no fast path.
  EXPECT_FALSE(TerrainIndex(mesh, CartesianMapping({0.05, 0.02, -1})).gridFastPath());
}

TEST(GridFastPath, OnlyForGridsAndUntilAnInsertion) {
  const Heightfield f = fractalHeightfield(30, 30, 1.0, 5.0, 5);
  Mesh mesh = f.toMesh();
  TerrainIndex index(mesh, CartesianMapping());
  EXPECT_TRUE(index.gridFastPath());
  // Removing a triangle keeps the path (its cell falls back to the quadtree, which has none).
  ASSERT_TRUE(index.removePolygon(100));
  TerrainIndex slow(mesh, CartesianMapping(), quadtreeOnly());
  slow.removePolygon(100);
  std::mt19937_64 rng(6);
  for (int i = 0; i < 20000; ++i) {
    expectSame(index, slow, uniform(rng, 0, 29), uniform(rng, 0, 29), uniform(rng, -20, 20));
  }
  const std::vector<Eigen::Vector3d> plate{{5, 5, 100}, {9, 5, 100}, {9, 9, 100}};
  index.insertPolygon(plate);
  EXPECT_FALSE(index.gridFastPath());
  EXPECT_EQ(index.top(8, 6)->height, 100);
  // A grid with an extra overlapping polygon is not a grid.
  mesh.addTriangle(0, 1, 31);
  EXPECT_FALSE(TerrainIndex(mesh, CartesianMapping()).gridFastPath());
  // Nor is a warped one.
  Mesh warped = f.toMesh();
  warped.vertices[45].x() += 0.3;
  EXPECT_FALSE(TerrainIndex(warped, CartesianMapping()).gridFastPath());
}

}  // namespace

namespace {

// A cursor remembers the last triangle's plane: a walk through it answers as the plain queries,
// also when the same cursor moves to another index or the index is edited under it.
TEST(GridFastPath, CursorMemoAnswersAsPlainQueries) {
  const Heightfield f = fractalHeightfield(40, 40, 1.0, 8.0, 9);
  const Heightfield g = fractalHeightfield(40, 40, 1.0, 8.0, 10);
  TerrainIndex a(f.toMesh(), CartesianMapping()), b(g.toMesh(), CartesianMapping());
  ASSERT_TRUE(a.gridFastPath());
  Quadtree::Cursor cursor;
  std::mt19937_64 rng(11);
  double u = 3.3, v = 4.1;
  for (int i = 0; i < 20000; ++i) {
    u = std::clamp(u + uniform(rng, -0.05, 0.07), 0.0, 39.0);
    v = std::clamp(v + uniform(rng, -0.05, 0.06), 0.0, 39.0);
    const TerrainIndex& index = i % 1000 < 500 ? a : b;  // the cursor changes hands
    ASSERT_EQ(index.heightBelow(cursor, u, v, 1e300), index.heightBelow(u, v, 1e300)) << i;
    const auto hit = index.below(cursor, u, v, 1e300), plain = index.below(u, v, 1e300);
    ASSERT_EQ(hit.has_value(), plain.has_value());
    if (hit) {
      ASSERT_EQ(hit->polygon, plain->polygon);
    }
    if (i == 10000) {
      // Remove the triangle under the cursor: its memo must not answer for it any more.
      ASSERT_TRUE(a.below(u, v, 1e300).has_value());
      a.removePolygon(a.below(u, v, 1e300)->polygon);
    }
  }
}

TEST(GridFastPath, ConcurrentStatsQueriesAndDeferredBuild) {
  // Threads query heights, read the statistics and the memory (which build the deferred tree on
  // first need) and ask for every hit (which needs the tree) at once: the same answers as one
  // thread alone, and no race (scripts/sanitize.sh runs this under ThreadSanitizer).
  const Heightfield f = fractalHeightfield(200, 160, 1.0, 20.0, 21);
  const Mesh mesh = f.toMesh();
  const TerrainIndex index(mesh, CartesianMapping());
  ASSERT_TRUE(index.gridFastPath());
  std::vector<std::optional<double>> expect(400);
  for (int i = 0; i < 400; ++i) expect[i] = index.heightBelow(0.37 * i, 0.29 * i, 1e9);
  std::atomic<int> wrong{0};
  std::vector<std::thread> threads;
  for (int k = 0; k < 4; ++k) {
    threads.emplace_back([&, k] {
      for (int round = 0; round < 20; ++round) {
        for (int i = 0; i < 400; ++i) {
          if (index.heightBelow(0.37 * i, 0.29 * i, 1e9) != expect[i]) ++wrong;
        }
        if (k % 2 == 0) (void)index.memoryBytesNow();
        if (k == 1) (void)index.stats().tree.nodes;
        if (k == 3 && round == 5) (void)index.all(10.5, 20.25).size();
      }
    });
  }
  for (auto& t : threads) t.join();
  EXPECT_EQ(wrong.load(), 0);
  EXPECT_GT(index.stats().tree.nodes, 0u);
}

}  // namespace
