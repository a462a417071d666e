// Dynamic edits: after any random sequence of insertions and removals, every query answers as an
// index built from scratch on the live polygons.
#include <gtest/gtest.h>

#include <algorithm>
#include <numbers>
#include <cmath>
#include <limits>
#include <optional>
#include <random>
#include <span>

#include "qota/error.hpp"
#include "qota/quadtree.hpp"
#include "qota/terrain.hpp"
#include "random_terrain.hpp"

namespace {

using namespace qota;

using Polygon = std::vector<Eigen::Vector3d>;
constexpr double kInf = std::numeric_limits<double>::infinity();

double uniform(std::mt19937_64& rng, double lo, double hi) {
  return std::uniform_real_distribution<double>(lo, hi)(rng);
}

// A random convex polygon (corners at sorted angles on an ellipse, on a tilted plane) around
// (cx, cy), any winding.
Polygon randomPlate(std::mt19937_64& rng, double cx, double cy, double size) {
  const int n = 3 + static_cast<int>(rng() % 5);
  std::vector<double> ang(n);
  for (double& a : ang) a = uniform(rng, 0, 2 * std::numbers::pi);
  std::sort(ang.begin(), ang.end());
  const double rx = size * uniform(rng, 0.1, 1), ry = size * uniform(rng, 0.1, 1);
  const double cz = uniform(rng, -8, 8), sx = uniform(rng, -0.5, 0.5), sy = uniform(rng, -0.5, 0.5);
  Polygon p;
  for (double a : ang) {
    const double x = cx + rx * std::cos(a), y = cy + ry * std::sin(a);
    p.emplace_back(x, y, cz + sx * (x - cx) + sy * (y - cy));
  }
  if (rng() % 2) std::reverse(p.begin(), p.end());
  return p;
}

// The live polygons (in id order) as a mesh, and for each of its polygons the edited id.
Mesh liveMesh(const std::vector<std::optional<Polygon>>& polygons, std::vector<std::uint32_t>& idOf) {
  Mesh mesh;
  idOf.clear();
  for (std::uint32_t id = 0; id < polygons.size(); ++id) {
    if (!polygons[id]) continue;
    std::vector<std::uint32_t> idx;
    for (const auto& c : *polygons[id]) idx.push_back(mesh.addVertex(c));
    mesh.addPolygon(idx);
    idOf.push_back(id);
  }
  return mesh;
}

// Compares the edited index with one built from scratch on the live polygons (in id order).
void expectMatchesScratch(const CartesianIndex& edited, const std::vector<std::optional<Polygon>>& polygons,
                          const CartesianMapping& mapping, std::mt19937_64& rng) {
  std::vector<std::uint32_t> idOf;  // scratch polygon -> edited id
  const Mesh mesh = liveMesh(polygons, idOf);
  const CartesianIndex scratch(mesh, mapping);
  EXPECT_EQ(edited.stats().triangles, scratch.stats().triangles);
  EXPECT_EQ(edited.stats().leftOut, scratch.stats().leftOut);
  const Box2 box = scratch.stats().domain;
  // exact: a random point, where the answer is unambiguous (same polygon, same height bit for
  // bit); else a point on shared corners, where equally near triangles differ by rounding (the
  // same height within it, whichever of them answers).
  auto check = [&](double u, double v, double h, bool exact) {
    const auto a = edited.below(u, v, h), b = scratch.below(u, v, h);
    ASSERT_EQ(a.has_value(), b.has_value()) << u << " " << v << " " << h;
    if (a && exact) {
      ASSERT_EQ(a->height, b->height);
      ASSERT_EQ(a->polygon, idOf[b->polygon]);
    } else if (a) {
      ASSERT_NEAR(a->height, b->height, 1e-9 * (1 + std::fabs(b->height)));
    }
    const auto c = edited.above(u, v, h), d = scratch.above(u, v, h);
    ASSERT_EQ(c.has_value(), d.has_value());
    if (c && exact) {
      ASSERT_EQ(c->polygon, idOf[d->polygon]);
    }
  };
  std::vector<Point2> points;
  std::vector<double> zs;
  for (int i = 0; i < 3000; ++i) {
    points.push_back({uniform(rng, box.ulo - 1, box.uhi + 1), uniform(rng, box.vlo - 1, box.vhi + 1)});
    zs.push_back(uniform(rng, -10, 10));
    check(points.back().u, points.back().v, zs.back(), true);
  }
  // The edited tree's batches (a pipelined descent through the jump table the edits refreshed):
  // the single queries' answers.
  std::vector<std::optional<double>> batch(points.size());
  edited.heightsBelow(points, zs, batch);
  for (std::size_t i = 0; i < points.size(); ++i) {
    ASSERT_EQ(batch[i], edited.heightBelow(points[i].u, points[i].v, zs[i])) << points[i].u << " " << points[i].v;
  }
  // Exactly at corners (from just above them: a point exactly on the surface is below or above
  // it within rounding): shared edges and vertices must not fall through.
  for (const auto& v : mesh.vertices) {
    const Eigen::Vector3d m = mapping.toMapped(v);
    check(m.x(), m.y(), m.z() + 1e-6, false);
  }
}

TEST(Edits, RandomSequencesMatchARebuild) {
  for (std::uint64_t seed = 1; seed <= 4; ++seed) {
    std::mt19937_64 rng(seed);
    test::RandomTerrainSpec spec;
    spec.grid = 25;
    spec.plates = 20;
    spec.offsetX = seed == 3 ? 4e5 : 0;  // map coordinates in one run
    const Mesh base = test::randomTerrain(spec, seed);
    const CartesianMapping mapping(seed == 2 ? Eigen::Vector3d(0.2, -0.1, -1) : Eigen::Vector3d(0, 0, -1),
                                   Eigen::Vector3d(spec.offsetX, 0, 0));
    CartesianIndex index(base, mapping, IndexOptions{{4, 12}});  // small leaves: many splits
    std::vector<std::optional<Polygon>> polygons;
    for (std::size_t p = 0; p < base.polygonCount(); ++p) {
      Polygon corners;
      for (std::uint32_t i : base.polygon(p)) corners.push_back(base.vertices[i]);
      polygons.emplace_back(corners);
    }
    const double extent = (spec.grid - 1) * spec.cell;
    for (int step = 1; step <= 300; ++step) {
      const double r = uniform(rng, 0, 1);
      if (r < 0.45) {
        Polygon p;
        if (r < 0.05) {
          p = randomPlate(rng, spec.offsetX + uniform(rng, -10, extent + 10), uniform(rng, -10, extent + 10), 6);
        } else if (r < 0.12) {
          // A copy of a live polygon: exact overlap and shared edges.
          const std::size_t k = rng() % polygons.size();
          if (!polygons[k]) continue;
          p = *polygons[k];
        } else {
          p = randomPlate(rng, spec.offsetX + uniform(rng, 0, extent), uniform(rng, 0, extent), 2);
        }
        const std::uint32_t id = index.insertPolygon(p);
        ASSERT_EQ(id, polygons.size());
        polygons.emplace_back(p);
      } else if (r < 0.95) {
        const std::uint32_t id = static_cast<std::uint32_t>(rng() % polygons.size());
        ASSERT_EQ(index.removePolygon(id), polygons[id].has_value());
        polygons[id].reset();
      } else {
        EXPECT_FALSE(index.removePolygon(static_cast<std::uint32_t>(polygons.size() + 5)));
      }
      if (step % 100 == 0) {
        expectMatchesScratch(index, polygons, mapping, rng);
        ASSERT_FALSE(::testing::Test::HasFailure()) << "seed " << seed << ", step " << step;
      }
    }
    // A non-convex polygon is refused and leaves the index as it was.
    const Polygon bad{{0, 0, 0}, {4, 0, 0}, {1, 1, 0}, {0, 4, 0}};
    EXPECT_THROW(index.insertPolygon(bad), Error);
    EXPECT_THROW(index.insertPolygon(Polygon{{0, 0, 0}, {1, 1, 1}}), Error);
    expectMatchesScratch(index, polygons, mapping, rng);
  }
}

TEST(Edits, InsertIntoAnEmptyIndex) {
  CartesianIndex index(Mesh{}, CartesianMapping());
  EXPECT_FALSE(index.top(0.5, 0.5));
  const std::uint32_t id = index.insertPolygon(Polygon{{0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}});
  EXPECT_EQ(id, 0u);
  ASSERT_TRUE(index.top(0.5, 0.5));
  EXPECT_EQ(index.top(0.5, 0.5)->height, 1.0);
  EXPECT_TRUE(index.removePolygon(id));
  EXPECT_FALSE(index.top(0.5, 0.5));
  EXPECT_FALSE(index.removePolygon(id));
}

}  // namespace

#include "qota/curved.hpp"
#include "random_globe.hpp"

namespace {

// The same property on a planet: random small plates above and below a bumpy sphere, some
// across the seam or on a pole, inserted and removed; the answers equal a rebuild's.
TEST(Edits, PlanetSequencesMatchARebuild) {
  std::mt19937_64 rng(21);
  Mesh base = test::unitIcosphere(4, rng, false);  // 5120 triangles, vertices on the poles
  for (auto& v : base.vertices) v *= 1000 * (1 + 0.01 * uniform(rng, -1, 1));
  const SphericalMapping mapping;
  SphericalIndex index(base, mapping);
  std::vector<std::optional<Polygon>> polygons;
  for (std::size_t p = 0; p < base.polygonCount(); ++p) {
    Polygon c;
    for (std::uint32_t i : base.polygon(p)) c.push_back(base.vertices[i]);
    polygons.emplace_back(c);
  }
  auto plate = [&]() {
    // A small triangle around a random direction (sometimes the pole or the seam), at a random
    // radius.
    double lon = uniform(rng, -180, 180), lat = std::asin(uniform(rng, -1, 1)) * 180 / std::numbers::pi;
    if (rng() % 8 == 0) lat = 90;
    if (rng() % 8 == 0) lon = 180;
    const double r = 1000 * uniform(rng, 0.97, 1.03), size = uniform(rng, 5, 60);
    const Eigen::Vector3d c = mapping.toWorld({lon, lat, r});
    const Eigen::Vector3d e1 = c.unitOrthogonal(), e2 = c.normalized().cross(e1);
    Polygon p;
    for (int k = 0; k < 3; ++k) {
      const double a = 2 * std::numbers::pi * k / 3 + uniform(rng, -0.3, 0.3);
      p.push_back(c + size * (std::cos(a) * e1 + std::sin(a) * e2));
    }
    return p;
  };
  auto compare = [&]() {
    std::vector<std::uint32_t> idOf;
    const SphericalIndex scratch(liveMesh(polygons, idOf), mapping);
    EXPECT_EQ(index.stats().triangles, scratch.stats().triangles);
    for (int i = 0; i < 3000; ++i) {
      const double u = uniform(rng, -180, 180), v = i % 100 == 0 ? 90.0 : uniform(rng, -90, 90);
      const double h = 1000 * uniform(rng, 0.95, 1.05);
      const auto a = index.below(u, v, h), b = scratch.below(u, v, h);
      ASSERT_EQ(a.has_value(), b.has_value()) << u << " " << v;
      if (a) {
        ASSERT_EQ(a->height, b->height);
        ASSERT_EQ(a->polygon, idOf[b->polygon]);
      }
    }
  };
  for (int step = 1; step <= 300; ++step) {
    if (uniform(rng, 0, 1) < 0.5) {
      const Polygon p = plate();
      ASSERT_EQ(index.insertPolygon(p), polygons.size());
      polygons.emplace_back(p);
    } else {
      const auto id = static_cast<std::uint32_t>(rng() % polygons.size());
      ASSERT_EQ(index.removePolygon(id), polygons[id].has_value());
      polygons[id].reset();
    }
    if (step % 100 == 0) compare();
  }
}

// A station whose relief is dug out and rebuilt, and a tube extended past its end (the tree's
// box grows).
TEST(Edits, StationGrows) {
  std::mt19937_64 rng(22);
  const Mesh base = test::bumpyTube(60, 11, 100.0, 100.0, 0.02, rng);
  CylindricalIndex index(base, CylindricalMapping());
  // A floor panel at radius 100 from angle 30 to 60, 55 to 65 m along the axis: past the end.
  auto at = [](double deg, double z) {
    return Eigen::Vector3d(100 * std::cos(deg * std::numbers::pi / 180), 100 * std::sin(deg * std::numbers::pi / 180),
                           z);
  };
  EXPECT_FALSE(index.top(45, 60).has_value());
  // A cursor kept across the edits sees them as the plain queries do (its leaf is of the tree
  // before them).
  Cursor cursor;
  EXPECT_FALSE(index.height(cursor, 45, 60).has_value());
  EXPECT_FALSE(index.height(cursor, 45.01, 60).has_value());
  const std::uint32_t id = index.insertPolygon(Polygon{at(30, 55), at(60, 55), at(60, 65), at(30, 65)});
  ASSERT_TRUE(index.top(45, 60).has_value());
  EXPECT_EQ(index.top(45, 60)->polygon, id);
  ASSERT_TRUE(index.height(cursor, 45.02, 60).has_value());
  EXPECT_EQ(*index.height(cursor, 45.02, 60), index.top(45.02, 60)->height);
  EXPECT_TRUE(index.removePolygon(id));
  EXPECT_FALSE(index.top(45, 60).has_value());
  EXPECT_FALSE(index.height(cursor, 45.03, 60).has_value());
  EXPECT_TRUE(index.top(45, 0).has_value());
}

// A flat square of n x n jittered cells (no regular grid: the quadtree answers) at height z.
Mesh jitteredFlat(int n, double z) {
  Mesh mesh;
  for (int y = 0; y <= n; ++y) {
    for (int x = 0; x <= n; ++x) mesh.addVertex({x + 0.01 * ((x * 7 + y * 3) % 5), y + 0.01 * ((x * 5 + y) % 3), z});
  }
  const auto at = [n](int x, int y) { return static_cast<std::uint32_t>(y * (n + 1) + x); };
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      mesh.addTriangle(at(x, y), at(x + 1, y), at(x + 1, y + 1));
      mesh.addTriangle(at(x, y), at(x + 1, y + 1), at(x, y + 1));
    }
  }
  return mesh;
}

// A cursor kept across insertions and removals, or taken from one index to another and back,
// answers the terrain there now: the plates stacked over a point by construction, and the other
// index's own height.
TEST(Edits, CursorsKeptAcrossEditsOrTakenToAnotherIndex) {
  CartesianIndex index(jitteredFlat(40, 0.0), CartesianMapping());
  const CartesianIndex other(jitteredFlat(40, 7.0), CartesianMapping());
  Cursor cursor;
  double u = 10.2;
  const auto next = [&u] { return u += 0.001; };  // steps well inside one leaf
  for (int k = 0; k < 5; ++k) EXPECT_EQ(index.height(cursor, next(), 10.2), 0.0);
  std::vector<std::uint32_t> ids;
  for (int k = 0; k < 20; ++k) {
    const double z = 5.0 + k;
    ids.push_back(index.insertPolygon(Polygon{{10.0, 10.0, z}, {10.6, 10.0, z}, {10.0, 10.6, z}}));
    EXPECT_EQ(index.height(cursor, next(), 10.2), z) << "after inserting plate " << k;
    const auto hit = index.below(cursor, next(), 10.2, kInf);
    ASSERT_TRUE(hit.has_value());
    EXPECT_EQ(hit->polygon, ids.back());
    EXPECT_EQ(index.heightBelow(cursor, next(), 10.2, z - 0.5), k == 0 ? 0.0 : z - 1);
    EXPECT_EQ(other.height(cursor, next(), 10.2), 7.0) << "the other index, after plate " << k;
  }
  for (int k = 19; k >= 0; --k) {
    ASSERT_TRUE(index.removePolygon(ids[static_cast<std::size_t>(k)]));
    EXPECT_EQ(index.height(cursor, next(), 10.2), k == 0 ? 0.0 : 4.0 + k) << "after removing plate " << k;
  }
}

// A cursor used with an index, then with another built later in the same memory (a loop over
// tiles, an optional re-emplaced), answers the new one: on the grid path (a regular grid: the
// cursor's memo of the last triangle's plane) and on the quadtree's (a jittered grid).
TEST(Edits, ACursorMeetsAnIndexBuiltInTheSameMemoryAsAnother) {
  const auto grid = [](double z, double jitter) {
    Mesh mesh = jitteredFlat(40, z);
    if (jitter == 0) {
      for (auto& p : mesh.vertices) p.x() = std::round(p.x()), p.y() = std::round(p.y());
    }
    return mesh;
  };
  for (const double jitter : {0.0, 0.01}) {
    std::optional<CartesianIndex> index;
    Cursor cursor;
    double u = 10.2;
    for (int k = 0; k < 6; ++k) {
      const double z = 3.0 * k;
      index.emplace(grid(z, jitter), CartesianMapping());
      ASSERT_EQ(index->gridFastPath(), jitter == 0);
      for (int i = 0; i < 3; ++i) {
        EXPECT_EQ(index->height(cursor, u += 0.001, 10.3), z) << "index " << k << ", jitter " << jitter;
      }
    }
  }
}

}  // namespace

// The build keeps its children's item lists a set a depth, sized once for every depth a build can
// reach. A tree built and edited with a small Maxdepth, then built again deeper, must size them
// again before the recursion holds any (sanitizers see a use after free otherwise); the deeper tree
// then finds every item where its box is.
TEST(Edits, RebuildDeeperAfterAnInsert) {
  std::vector<qota::Box2> boxes;
  for (int i = 0; i < 64; ++i) {
    for (int j = 0; j < 64; ++j) boxes.push_back({i / 64.0, j / 64.0, (i + 0.5) / 64.0, (j + 0.5) / 64.0});
  }
  const auto meets = [&boxes](std::uint32_t t, const qota::Box2& b) {
    const qota::Box2& a = boxes[t];
    return !(a.ulo > b.uhi || a.uhi < b.ulo || a.vlo > b.vhi || a.vhi < b.vlo);
  };
  qota::Quadtree tree;
  const qota::Box2 square{0, 0, 1, 1};
  tree.build(static_cast<std::uint32_t>(boxes.size()), square, qota::QuadtreeOptions{4, 3}, meets);
  boxes.push_back({0.1, 0.1, 0.11, 0.11});
  tree.insert(static_cast<std::uint32_t>(boxes.size() - 1), meets, [](std::span<std::uint32_t>) { return false; });
  tree.build(static_cast<std::uint32_t>(boxes.size()), square, qota::QuadtreeOptions{1, 12}, meets);
  EXPECT_GT(tree.stats().depth, 3u);
  for (std::uint32_t t = 0; t < boxes.size(); ++t) {
    const qota::Box2& b = boxes[t];
    const auto items = tree.leafItems(0.5 * (b.ulo + b.uhi), 0.5 * (b.vlo + b.vhi));
    EXPECT_NE(std::find(items.begin(), items.end(), t), items.end()) << t;
  }
}
