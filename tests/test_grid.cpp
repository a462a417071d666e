// The grid fast path answers exactly as the quadtree: on the real DEM, a rotated grid and a
// synthetic one, at random points, exactly at vertices, on edges and on cut lines; it turns
// itself off for meshes that are not grids and after insertions.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <atomic>
#include <functional>
#include <random>
#include <span>
#include <thread>

#include "qota/dem.hpp"
#include "qota/error.hpp"
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
void expectSame(const CartesianIndex& fast, const CartesianIndex& slow, double u, double v, double z) {
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
  const CartesianIndex fast(mesh, mapping), slow(mesh, mapping, quadtreeOnly());
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
  const CartesianIndex lean(mesh, mapping);
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
  const DemTerrain dem =
      loadDem(QOTA_DATA_DIR "/mt_rainier_90m.tif", {.lonLatAsCartesian = true});  // with nodata holes
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
  EXPECT_FALSE(CartesianIndex(mesh, CartesianMapping({0.05, 0.02, -1})).gridFastPath());
}

TEST(GridFastPath, OnlyForGridsAndUntilAnInsertion) {
  const Heightfield f = fractalHeightfield(30, 30, 1.0, 5.0, 5);
  Mesh mesh = f.toMesh();
  CartesianIndex index(mesh, CartesianMapping());
  EXPECT_TRUE(index.gridFastPath());
  // Removing a triangle keeps the path (its cell falls back to the quadtree, which has none).
  ASSERT_TRUE(index.removePolygon(100));
  CartesianIndex slow(mesh, CartesianMapping(), quadtreeOnly());
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
  EXPECT_FALSE(CartesianIndex(mesh, CartesianMapping()).gridFastPath());
  // Nor is a warped one.
  Mesh warped = f.toMesh();
  warped.vertices[45].x() += 0.3;
  EXPECT_FALSE(CartesianIndex(warped, CartesianMapping()).gridFastPath());
}

}  // namespace

namespace {

// A cursor remembers the last triangle's plane: a walk through it answers as the plain queries,
// also when the same cursor moves to another index or the index is edited under it.
TEST(GridFastPath, CursorMemoAnswersAsPlainQueries) {
  const Heightfield f = fractalHeightfield(40, 40, 1.0, 8.0, 9);
  const Heightfield g = fractalHeightfield(40, 40, 1.0, 8.0, 10);
  CartesianIndex a(f.toMesh(), CartesianMapping()), b(g.toMesh(), CartesianMapping());
  ASSERT_TRUE(a.gridFastPath());
  Cursor cursor;
  std::mt19937_64 rng(11);
  double u = 3.3, v = 4.1;
  for (int i = 0; i < 20000; ++i) {
    u = std::clamp(u + uniform(rng, -0.05, 0.07), 0.0, 39.0);
    v = std::clamp(v + uniform(rng, -0.05, 0.06), 0.0, 39.0);
    const CartesianIndex& index = i % 1000 < 500 ? a : b;  // the cursor changes hands
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
  const CartesianIndex index(mesh, CartesianMapping());
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

// An index built from a GridMesh is the index of the Mesh it stands for (GridMesh::toMesh), bit
// for bit: the same polygons, statistics and answers at random points, vertices and edges, with
// holes, either turn, a sheared lattice, a lattice off the affine grid, the quadtree only, and
// the same refusal of a non-finite vertex. And the lean grid made straight from the lattice
// (GridPath::setUpLattice, the raster sampler's large tiles) answers as the index wherever it
// decides.
void expectGridMeshIsItsMesh(const GridMesh& grid, const CartesianMapping& mapping, const IndexOptions& options,
                             std::uint64_t seed) {
  SCOPED_TRACE(seed);
  const Mesh mesh = grid.toMesh();
  const CartesianIndex direct(grid, mapping, options), viaMesh(mesh, mapping, options);
  ASSERT_EQ(direct.gridFastPath(), viaMesh.gridFastPath());
  ASSERT_EQ(direct.memoryBytesNow(), viaMesh.memoryBytesNow());
  const IndexStats a = direct.stats(), b = viaMesh.stats();
  ASSERT_EQ(a.polygons, b.polygons);
  ASSERT_EQ(a.triangles, b.triangles);
  ASSERT_EQ(a.leftOut, b.leftOut);
  ASSERT_EQ(a.vertices, b.vertices);
  ASSERT_EQ(a.tree.nodes, b.tree.nodes);
  ASSERT_EQ(a.tree.leaves, b.tree.leaves);
  ASSERT_EQ(a.tree.references, b.tree.references);
  ASSERT_EQ(a.memoryBytes, b.memoryBytes);
  if (mesh.indices.empty()) return;
  const Box2 box = a.domain;
  ASSERT_EQ(box.ulo, b.domain.ulo);
  ASSERT_EQ(box.vhi, b.domain.vhi);
  std::mt19937_64 rng(seed);
  std::vector<Point2> points;
  for (int i = 0; i < 20000; ++i) {
    points.push_back({uniform(rng, box.ulo - 1e-3 * (box.uhi - box.ulo), box.uhi),
                      uniform(rng, box.vlo, box.vhi + 1e-3 * (box.vhi - box.vlo))});
  }
  for (int i = 0; i < 5000; ++i) {
    const auto p = mesh.polygon(rng() % mesh.polygonCount());
    const Eigen::Vector3d c = mapping.toMapped(mesh.vertices[p[0]]), d = mapping.toMapped(mesh.vertices[p[1]]);
    const double s = uniform(rng, 0, 1);
    points.push_back({c.x(), c.y()});
    points.push_back({c.x() + s * (d.x() - c.x()), c.y() + s * (d.y() - c.y())});
  }
  for (const Point2& p : points) {
    const double z = uniform(rng, -2000, 4000);
    const auto x = direct.below(p.u, p.v, z), y = viaMesh.below(p.u, p.v, z);
    ASSERT_EQ(x.has_value(), y.has_value()) << p.u << " " << p.v;
    if (x) {
      ASSERT_EQ(x->height, y->height);
      ASSERT_EQ(x->polygon, y->polygon);
    }
    const auto all = direct.all(p.u, p.v), allToo = viaMesh.all(p.u, p.v);
    ASSERT_EQ(all.size(), allToo.size());
  }
  std::vector<std::optional<double>> h(points.size()), hToo(points.size());
  direct.heightsBelow(points, 1e300, h);
  viaMesh.heightsBelow(points, 1e300, hToo);
  ASSERT_EQ(h, hToo);
  // And against brute force, without the index: at the random points clearly inside one
  // triangle of the mesh (its mapped corners, barycentric weights over 1e-6), that triangle's
  // linear interpolation; clearly outside every triangle, no terrain. (The first 8,000 random
  // points, the mapped corners computed once: the brute force was most of this test's time.)
  std::vector<std::array<Eigen::Vector3d, 3>> triangles(mesh.polygonCount());
  for (std::size_t t = 0; t < mesh.polygonCount(); ++t) {
    const auto p = mesh.polygon(t);
    for (int k = 0; k < 3; ++k) triangles[t][k] = mapping.toMapped(mesh.vertices[p[k]]);
  }
  std::size_t inside = 0;
  for (std::size_t i = 0; i < 8000; ++i) {
    const Point2 q = points[i];
    double want = NAN;
    bool near = false;
    for (std::size_t t = 0; t < mesh.polygonCount() && std::isnan(want); ++t) {
      const auto& c = triangles[t];
      const double area = (c[1].x() - c[0].x()) * (c[2].y() - c[0].y()) - (c[1].y() - c[0].y()) * (c[2].x() - c[0].x());
      if (area == 0) continue;
      const double w1 = ((q.u - c[0].x()) * (c[2].y() - c[0].y()) - (q.v - c[0].y()) * (c[2].x() - c[0].x())) / area;
      const double w2 = ((c[1].x() - c[0].x()) * (q.v - c[0].y()) - (c[1].y() - c[0].y()) * (q.u - c[0].x())) / area;
      const double w0 = 1 - w1 - w2;
      const double least = std::min({w0, w1, w2});
      if (least > 1e-6) want = w0 * c[0].z() + w1 * c[1].z() + w2 * c[2].z();
      near = near || least > -1e-6;
    }
    if (!std::isnan(want)) {
      ++inside;
      ASSERT_TRUE(h[i].has_value()) << i;
      ASSERT_NEAR(*h[i], want, 1e-6 * (1 + std::fabs(want))) << i;
    } else if (!near) {
      ASSERT_FALSE(h[i].has_value()) << i;
    }
  }
  EXPECT_GT(inside, 1000u);

  // The lean grid alone, from the same mapped vertices.
  if (!direct.gridFastPath() || !options.gridFastPath.value_or(true)) return;
  std::vector<Point2> corners(grid.vertices.size());
  std::vector<double> heights(grid.vertices.size());
  for (std::size_t k = 0; k < corners.size(); ++k) {
    const Eigen::Vector3d m = mapping.toMapped(grid.vertices[k]);
    corners[k] = {m.x(), m.y()}, heights[k] = m.z();
  }
  detail::GridPath lean;
  ASSERT_TRUE(lean.setUpLattice(grid.width, grid.height, corners, heights));
  std::vector<double> leanHeights(points.size());
  std::vector<std::uint8_t> decided(points.size());
  lean.leanHeights(corners, heights, points, leanHeights.data(), decided.data());
  std::size_t counted[3] = {0, 0, 0};
  for (std::size_t i = 0; i < points.size(); ++i) {
    ++counted[decided[i]];
    if (decided[i] == detail::GridPath::kHeight) {
      ASSERT_EQ(std::optional<double>(leanHeights[i]), h[i]) << i;
    } else if (decided[i] == detail::GridPath::kNoTerrain) {
      ASSERT_FALSE(h[i].has_value()) << i;
    }
  }
  EXPECT_GT(counted[detail::GridPath::kHeight], points.size() / 2);
  EXPECT_GT(counted[detail::GridPath::kUndecided], 0u);  // the vertices and edges
}

// A w x h raster's vertices over a geotransform, heights from `height` (NaN: no data).
std::vector<Eigen::Vector3d> latticeVertices(int w, int h, const std::array<double, 6>& g,
                                             const std::function<double(int, int)>& height) {
  std::vector<Eigen::Vector3d> v;
  for (int r = 0; r < h; ++r) {
    for (int c = 0; c < w; ++c) {
      v.emplace_back(g[0] + (c + 0.5) * g[1] + (r + 0.5) * g[2], g[3] + (c + 0.5) * g[4] + (r + 0.5) * g[5],
                     height(c, r));
    }
  }
  return v;
}

TEST(GridMesh, IndexIsItsMeshsIndex) {
  std::mt19937_64 rng(41);
  const auto noise = [&](int c, int r) {
    const bool hole = (c - 20) * (c - 20) + (r - 14) * (r - 14) < 30 || (c == 33 && r > 5) || uniform(rng, 0, 1) < 0.01;
    return hole ? NAN : std::floor(uniform(rng, -50, 3000));
  };
  // North up (Int16-like heights in float), with holes.
  const std::array<double, 6> northUp{5e5, 30, 0, 5.2e6, 0, -30};
  const auto v1 = latticeVertices(47, 31, northUp, noise);
  const CartesianMapping centred({0, 0, -1}, {5e5 + 23 * 30, 5.2e6 - 15 * 30, 0});
  expectGridMeshIsItsMesh({.width = 47, .height = 31, .vertices = v1}, centred, {}, 1);
  // Either turn, and the quadtree only.
  expectGridMeshIsItsMesh({.width = 47, .height = 31, .vertices = v1, .reverse = true}, centred, {}, 2);
  IndexOptions tree;
  tree.gridFastPath = false;
  expectGridMeshIsItsMesh({.width = 47, .height = 31, .vertices = v1}, centred, tree, 3);
  // Sheared and rotated, fractional heights (not exact in float): no u per column.
  const std::array<double, 6> sheared{5e5, 30, 4, 5.2e6, -3, -30};
  const auto v2 = latticeVertices(40, 36, sheared, [&](int c, int r) {
    return c == 7 && r < 20 ? NAN : 100 + 40 * std::sin(0.3 * c) * std::cos(0.2 * r) + uniform(rng, 0, 1e-3);
  });
  expectGridMeshIsItsMesh({.width = 40, .height = 36, .vertices = v2}, CartesianMapping({0, 0, -1}, {5e5, 5.2e6, 0}),
                          {}, 4);
  // Off the affine grid (a vertex moved by a thousandth of a cell): the general path, alike.
  auto v3 = v1;
  v3[200].x() += 0.03;
  const CartesianIndex moved(GridMesh{.width = 47, .height = 31, .vertices = v3}, centred);
  EXPECT_FALSE(moved.gridFastPath());
  expectGridMeshIsItsMesh({.width = 47, .height = 31, .vertices = v3}, centred, {}, 5);
  // Under a tilted gravity the heights move the projected vertices off the grid.
  expectGridMeshIsItsMesh({.width = 40, .height = 36, .vertices = v2},
                          CartesianMapping({0.05, 0.02, -1}, {5e5, 5.2e6, 0}), {}, 6);
  // No data at all, one row, the smallest grid.
  const auto none = latticeVertices(5, 4, northUp, [](int, int) { return NAN; });
  expectGridMeshIsItsMesh({.width = 5, .height = 4, .vertices = none}, centred, {}, 7);
  const auto row = latticeVertices(6, 1, northUp, [](int c, int) { return c; });
  expectGridMeshIsItsMesh({.width = 6, .height = 1, .vertices = row}, centred, {}, 8);
  const auto two = latticeVertices(2, 2, northUp, [](int c, int r) { return c + 2 * r; });
  expectGridMeshIsItsMesh({.width = 2, .height = 2, .vertices = two}, centred, {}, 9);
}

TEST(GridMesh, RefusesAsItsMesh) {
  const std::array<double, 6> northUp{0, 1, 0, 0, 0, -1};
  auto v = latticeVertices(4, 3, northUp, [](int c, int r) { return c + r; });
  v[5].z() = INFINITY;
  const GridMesh grid{.width = 4, .height = 3, .vertices = v};
  std::string direct, viaMesh;
  try {
    CartesianIndex index(grid, CartesianMapping());
  } catch (const Error& e) {
    direct = e.what();
  }
  try {
    CartesianIndex index(grid.toMesh(), CartesianMapping());
  } catch (const Error& e) {
    viaMesh = e.what();
  }
  EXPECT_FALSE(direct.empty());
  EXPECT_EQ(direct, viaMesh);
  EXPECT_THROW(CartesianIndex(GridMesh{.width = 5, .height = 3, .vertices = v}, CartesianMapping()), Error);
}

}  // namespace
