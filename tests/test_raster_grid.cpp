// The raster triangulation and its closure, checked by counting: edges shared by two triangles
// each way round (a closed, consistently wound surface), rings that hold every triangle of a
// vertex, and the documented layout of the inner triangles.
#include <gtest/gtest.h>

#include <map>
#include <set>

#include "qota/dem.hpp"
#include "qota/raster_grid.hpp"

namespace {

using qota::RasterGrid;

// Directed edges of every triangle: how often each appears.
std::map<std::pair<std::uint32_t, std::uint32_t>, int> directedEdges(const RasterGrid& g) {
  std::map<std::pair<std::uint32_t, std::uint32_t>, int> edges;
  for (std::size_t t = 0; t < g.triangleCount(); ++t) {
    const auto c = g.triangle(t);
    for (int k = 0; k < 3; ++k) ++edges[{c[k], c[(k + 1) % 3]}];
  }
  return edges;
}

TEST(RasterGrid, InnerTrianglesAreTheDocumentedSplit) {
  const RasterGrid g(5, 4, {});
  EXPECT_EQ(g.triangleCount(), 2u * 4 * 3);
  EXPECT_EQ(g.vertexCount(), 20u);
  for (int r = 0; r + 1 < 4; ++r) {
    for (int c = 0; c + 1 < 5; ++c) {
      const std::uint32_t tl = r * 5 + c, tr = tl + 1, bl = tl + 5, br = bl + 1;
      const std::size_t t = 2 * (r * 4 + c);
      EXPECT_EQ(g.triangle(t), (std::array<std::uint32_t, 3>{tl, bl, br}));
      EXPECT_EQ(g.triangle(t + 1), (std::array<std::uint32_t, 3>{tl, br, tr}));
    }
  }
}

TEST(RasterGrid, BorderReachesTheEdgeWithTheNearestCentresHeights) {
  const int w = 6, h = 4;
  const RasterGrid g(w, h, {.border = true});
  EXPECT_EQ(g.extraVertices().size(), static_cast<std::size_t>(2 * w + 2 * h + 4));
  EXPECT_EQ(g.triangleCount(), g.innerTriangleCount() + 4u * (w + h));
  for (const auto& e : g.extraVertices()) {
    // On the raster's edge, beside the cell whose height it takes.
    EXPECT_TRUE(e.col == 0 || e.col == w || e.row == 0 || e.row == h);
    const double cc = static_cast<double>(e.pixel % w) + 0.5, cr = static_cast<double>(e.pixel / w) + 0.5;
    EXPECT_LE(std::fabs(e.col - cc), 0.5);
    EXPECT_LE(std::fabs(e.row - cr), 0.5);
  }
  // An open surface, consistently wound: no directed edge twice, every inner edge both ways.
  const auto edges = directedEdges(g);
  std::size_t boundary = 0;
  for (const auto& [e, n] : edges) {
    EXPECT_EQ(n, 1);
    boundary += edges.count({e.second, e.first}) == 0;
  }
  EXPECT_EQ(boundary, static_cast<std::size_t>(2 * (w + 1) + 2 * (h + 1)));  // the lattice's outline
  // Every cell is closed round, and its ring holds exactly its triangles.
  for (int r = 0; r < h; ++r) {
    for (int c = 0; c < w; ++c) {
      std::uint32_t ring[RasterGrid::kMaxRing];
      bool closed = false;
      const int n = g.ring(r, c, ring, closed);
      EXPECT_TRUE(closed);
      std::set<std::uint32_t> expected;
      for (std::size_t t = 0; t < g.triangleCount(); ++t) {
        for (const auto v : g.triangle(t)) {
          if (v == static_cast<std::uint32_t>(r * w + c)) expected.insert(static_cast<std::uint32_t>(t));
        }
      }
      EXPECT_EQ(std::set<std::uint32_t>(ring, ring + n), expected) << r << ' ' << c;
      EXPECT_TRUE(std::is_sorted(ring, ring + n));
    }
  }
}

TEST(RasterGrid, GlobeWithSeamAndCapsIsAClosedSphere) {
  const int w = 12, h = 5;
  const RasterGrid g(w, h, {.border = true, .wrapsColumns = true, .northCap = true, .southCap = true});
  EXPECT_EQ(g.extraVertices().size(), 2u);  // the poles: no border where the surface closes
  const auto edges = directedEdges(g);
  for (const auto& [e, n] : edges) {
    EXPECT_EQ(n, 1);
    EXPECT_EQ(edges.count({e.second, e.first}), 1u) << e.first << "->" << e.second;  // closed, one winding
  }
  // Euler: V - E + F = 2 for a sphere.
  const long v = static_cast<long>(g.vertexCount()), f = static_cast<long>(g.triangleCount());
  const long e = static_cast<long>(edges.size() / 2);
  EXPECT_EQ(v - e + f, 2);
  for (int r = 0; r < h; ++r) {
    for (int c = 0; c < w; ++c) {
      std::uint32_t ring[RasterGrid::kMaxRing];
      bool closed = false;
      EXPECT_EQ(g.ring(r, c, ring, closed), r == 0 || r == h - 1 ? 5 : 6) << r << ' ' << c;
      EXPECT_TRUE(closed);
    }
  }
  // Round the globe without caps, the border runs above and below: a closed band's outline.
  const RasterGrid band(w, h, {.border = true, .wrapsColumns = true});
  std::size_t boundary = 0;
  const auto be = directedEdges(band);
  for (const auto& [edge, n] : be) boundary += be.count({edge.second, edge.first}) == 0;
  EXPECT_EQ(boundary, 2u * w);
}

TEST(RasterGrid, SurfacePointClampsTheOuterHalfPixel) {
  qota::DemTerrain dem;
  dem.width = 4, dem.height = 3;
  dem.geotransform = {100, 2, 0, 50, 0, -2};
  // Inside the centres: unchanged; in the outer half pixel: onto the outermost centres' lines;
  // off the raster: none.
  EXPECT_EQ(*dem.surfacePoint(103.3, 46.1), (std::array<double, 2>{103.3, 46.1}));
  EXPECT_EQ(*dem.surfacePoint(100.2, 46.0), (std::array<double, 2>{101, 46.0}));
  EXPECT_EQ(*dem.surfacePoint(108, 50), (std::array<double, 2>{107, 49}));
  EXPECT_EQ(*dem.surfacePoint(100, 44), (std::array<double, 2>{101, 45}));
  EXPECT_FALSE(dem.surfacePoint(99.999, 46));
  EXPECT_FALSE(dem.surfacePoint(104, 43.9));
}

// The rule read backwards finds every inner triangle from its corners in any order, and nothing
// else: not the other diagonal, not a triangle across the row's end, not the closure's.
TEST(RasterGrid, InnerTriangleWithIsTheRuleBackwards) {
  // The documented numbering (raster_grid.hpp): the square (row, col) of a w-wide grid holds
  // triangles 2 (row (w - 1) + col), (TL, BL, BR), and the one after, (TL, BR, TR).
  const int w = 5, h = 4;
  const RasterGrid g(w, h, {.border = true});
  for (std::uint32_t r = 0; r + 1 < h; ++r) {
    for (std::uint32_t c = 0; c + 1 < w; ++c) {
      const std::uint32_t tl = r * w + c, tr = tl + 1, bl = tl + w, br = bl + 1;
      const std::uint64_t first = 2 * (r * (w - 1) + c);
      EXPECT_EQ(g.innerTriangleWith(tl, bl, br), first);
      EXPECT_EQ(g.innerTriangleWith(br, tl, bl), first);
      EXPECT_EQ(g.innerTriangleWith(tl, br, tr), first + 1);
      EXPECT_EQ(g.innerTriangleWith(tr, br, tl), first + 1);
    }
  }
  for (std::size_t t = g.innerTriangleCount(); t < g.triangleCount(); ++t) {
    const auto k = g.triangle(t);
    EXPECT_FALSE(g.innerTriangleWith(k[0], k[1], k[2]).has_value()) << "closure triangle " << t;
  }
  EXPECT_FALSE(g.innerTriangleWith(1, 5, 6).has_value());     // (TR, BL, BR): the other diagonal
  EXPECT_FALSE(g.innerTriangleWith(4, 9, 10).has_value());    // from the last column across the row's end
  EXPECT_FALSE(g.innerTriangleWith(15, 16, 21).has_value());  // below the last row
  EXPECT_FALSE(g.innerTriangleWith(0, 0, 6).has_value());
}

}  // namespace
