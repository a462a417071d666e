// Watertightness: queries exactly on shared vertices and edges never fall through.
#include <gtest/gtest.h>

#include <random>
#include <unordered_map>

#include "qota/predicates.hpp"

#include "qota/dem.hpp"
#include "qota/error.hpp"
#include "qota/synthetic.hpp"
#include "qota/terrain.hpp"

namespace {

using qota::CartesianIndex;
using qota::CartesianMapping;
using qota::Mesh;

// Queries at corners and on edges of random triangles of the mesh, in the mapped frame:
// - exactly on the geometry: at a corner, or anywhere on an axis-aligned edge. Such a point lies in
//   a closed triangle, so it must hit, whatever the edge (interior or boundary);
// - along an edge that is not axis-aligned (a + s (b - a), rounded: within an ulp of the edge, on
//   either side). Such a point must hit when the edge is interior, i.e. shared by two triangles
//   lying on opposite sides of it: the two close the gap between them.
// Points near boundary edges (the outline, the rim of a nodata hole) may round outside; they are
// not counted. Returns the number of misses.
struct EdgeKey {
  std::uint64_t key;
  bool operator==(const EdgeKey&) const = default;
};

std::uint64_t missesOnEdges(const Mesh& mesh, const CartesianIndex& index, std::uint64_t queries, std::uint64_t seed,
                            std::uint64_t* exactQueries = nullptr) {
  // For every edge, the side (+1/-1) of each triangle's third corner; interior edges have both.
  std::unordered_map<std::uint64_t, int> sides;
  auto mapped2 = [&](std::uint32_t i) {
    const Eigen::Vector3d m = index.mapping().toMapped(mesh.vertices[i]);
    return qota::Point2{m.x(), m.y()};
  };
  for (std::size_t p = 0; p < mesh.polygonCount(); ++p) {
    const auto t = mesh.polygon(p);
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t a = t[k], b = t[(k + 1) % 3], c = t[(k + 2) % 3];
      const std::uint64_t key = std::uint64_t(std::min(a, b)) << 32 | std::max(a, b);
      const int side = qota::orient2dSign(mapped2(std::min(a, b)), mapped2(std::max(a, b)), mapped2(c));
      sides[key] |= side > 0 ? 1 : side < 0 ? 2 : 0;
    }
  }
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<std::size_t> pick(0, mesh.polygonCount() - 1);
  std::uniform_real_distribution<double> t(0, 1);
  std::uint64_t misses = 0, exact = 0;
  for (std::uint64_t q = 0; q < queries; ++q) {
    const auto poly = mesh.polygon(pick(rng));
    const int k = static_cast<int>(q % 3);
    const std::uint32_t ia = poly[k], ib = poly[(k + 1) % 3];
    const qota::Point2 a = mapped2(ia), b = mapped2(ib);
    const bool axisAligned = a.u == b.u || a.v == b.v;
    const bool interior = sides[std::uint64_t(std::min(ia, ib)) << 32 | std::max(ia, ib)] == 3;
    double u, v;
    bool onGeometry = true;
    if (q % 4 == 0) {  // a shared vertex
      u = a.u, v = a.v;
    } else {  // along the edge: the midpoint, or anywhere
      const double s = q % 4 == 1 ? 0.5 : t(rng);
      u = a.u == b.u ? a.u : a.u + s * (b.u - a.u);
      v = a.v == b.v ? a.v : a.v + s * (b.v - a.v);
      onGeometry = axisAligned;
    }
    if (!onGeometry && !interior) continue;
    exact += onGeometry;
    if (!index.top(u, v)) ++misses;
  }
  if (exactQueries) *exactQueries = exact;
  return misses;
}

TEST(Watertight, RealDemMillionQueries) {
  const qota::DemTerrain dem = qota::loadDem(QOTA_DATA_DIR "/mt_rainier_90m.tif", {.lonLatAsCartesian = true});
  const CartesianIndex index(dem.mesh, dem.mapping);
  std::uint64_t exact = 0;
  EXPECT_EQ(missesOnEdges(dem.mesh, index, 1000000, 1, &exact), 0u);
  EXPECT_GT(exact, 600000u);  // vertices and the grid's axis-aligned edges
}

TEST(Watertight, TiltedGravityAndCoarseTree) {
  qota::Heightfield f = qota::fractalHeightfield(200, 200, 1.0, 20.0, 3);
  f.x0 = 1000.25;
  f.y0 = -77.5;
  const Mesh mesh = f.toMesh();
  for (const Eigen::Vector3d& g :
       {Eigen::Vector3d(0, 0, -1), Eigen::Vector3d(0.3, -0.2, -1), Eigen::Vector3d(-0.05, 0.01, -1)}) {
    for (const qota::QuadtreeOptions tree :
         {qota::QuadtreeOptions{}, qota::QuadtreeOptions{3, 12}, qota::QuadtreeOptions{50, 4}}) {
      const CartesianIndex index(mesh, CartesianMapping(g, Eigen::Vector3d(1100, 20, 0)), {tree});
      EXPECT_EQ(missesOnEdges(mesh, index, 100000, 7), 0u);
    }
  }
}

TEST(Watertight, JitteredTinAtAnyScale) {
  // Irregular triangles (a jittered grid: no edge axis-aligned), so points rounded onto an
  // interior edge fall within the triangle records' float error bound and go to the exact test;
  // they must hit, at any scale: 1e31 is beyond the floats' range there (every test exact).
  for (const double scale : {1e-30, 1.0, 1e25, 1e31}) {
    SCOPED_TRACE(scale);
    qota::Heightfield f = qota::fractalHeightfield(120, 120, 1.0, 20.0, 5);
    f.x0 = 3e5, f.y0 = -2e4;
    Mesh mesh = f.toMesh();
    std::mt19937_64 rng(8);
    std::uniform_real_distribution<double> jitter(-0.2, 0.2);  // a third of a cell's least height
    for (Eigen::Vector3d& v : mesh.vertices)
      v = Eigen::Vector3d(v.x() + jitter(rng), v.y() + jitter(rng), v.z()) * scale;
    const CartesianIndex index(mesh, CartesianMapping(Eigen::Vector3d(0.1, -0.05, -1), mesh.vertices[0]));
    std::uint64_t exact = 0;
    EXPECT_EQ(missesOnEdges(mesh, index, 100000, 3, &exact), 0u);
    EXPECT_GT(exact, 20000u);  // the vertices
  }
}

TEST(Watertight, PointsOnQuadtreeCutLines) {
  // A grid whose cut lines fall exactly on its vertices and edges: the quadtree's boundary rule
  // (ties go to the high side, boxes are closed in the build) must keep every point found.
  qota::Heightfield f = qota::fractalHeightfield(65, 65, 1.0, 5.0, 11);
  const Mesh mesh = f.toMesh();
  const CartesianIndex index(mesh, CartesianMapping(), {{2, 20}});
  std::uint64_t misses = 0;
  for (int i = 0; i <= 64 * 8; ++i) {
    for (int j = 0; j <= 64; ++j) {
      const double u = i / 8.0, v = j;
      if (!index.top(u, v)) ++misses;
      if (!index.top(v, u)) ++misses;
    }
  }
  EXPECT_EQ(misses, 0u);
  // The outer boundary of the domain is closed too.
  EXPECT_TRUE(index.top(0, 0));
  EXPECT_TRUE(index.top(64, 64));
  EXPECT_FALSE(index.top(std::nextafter(64.0, 65.0), 10));
}

TEST(Watertight, HolesNeverHit) {
  // A grid with every other cell removed: points strictly inside a removed cell miss; points on
  // the border of a removed cell hit the neighbours.
  Mesh m;
  const int n = 20;
  for (int j = 0; j <= n; ++j) {
    for (int i = 0; i <= n; ++i) m.addVertex({double(i), double(j), double((i * 7 + j * 3) % 5)});
  }
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      if ((i + j) % 2) continue;
      const auto a = static_cast<std::uint32_t>(j * (n + 1) + i);
      m.addTriangle(a, a + 1, a + n + 2);
      m.addTriangle(a, a + n + 2, a + n + 1);
    }
  }
  const CartesianIndex index(m, CartesianMapping());
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> t(0.0, 1.0);
  for (int q = 0; q < 20000; ++q) {
    const int i = static_cast<int>(t(rng) * n), j = static_cast<int>(t(rng) * n);
    const double fu = t(rng), fv = t(rng);
    if (fu == 0 || fv == 0) continue;
    const bool hole = (i + j) % 2;
    EXPECT_EQ(index.top(i + fu, j + fv).has_value(), !hole) << i << ' ' << j;
    if (i > 0) {
      EXPECT_TRUE(index.top(i, j + fv));  // an inner cell border touches a kept cell
    }
  }
}

}  // namespace

TEST(Quadtree, TooSmallMaxpolyStaysBounded) {
  // Two triangles share every diagonal: with Maxpoly 1 every leaf on an edge would split down to
  // Maxdepth 24 (about 10^11 nodes) under the paper's rule alone. The size floor (half a
  // triangle) and the split gain check keep the tree small, and the answers stay right.
  const qota::Heightfield f = qota::fractalHeightfield(50, 50, 1.0, 5.0, 1);
  const Mesh mesh = f.toMesh();
  const CartesianIndex index(mesh, CartesianMapping(), {{1, 24}});
  const auto& s = index.stats();
  EXPECT_LT(s.tree.references, 16 * s.triangles);
  EXPECT_LE(s.tree.depth, 8u);
  EXPECT_EQ(missesOnEdges(mesh, index, 20000, 3), 0u);
  double h = 0;
  ASSERT_TRUE(f.heightAt(20.3, 31.7, h));
  EXPECT_NEAR(index.top(20.3, 31.7)->height, h, 1e-12);
}
