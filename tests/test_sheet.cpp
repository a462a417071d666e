// The one-sheet proof (lib/core/planar_sheet.hpp) on meshes whose answer is known by their
// construction, and indexes built over sheets and over a ramp that winds over itself, against
// the brute-force oracle.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <random>
#include <vector>

#include "oracle.hpp"
#include "planar_sheet.hpp"
#include "qota/terrain.hpp"

namespace {

using qota::CartesianIndex;
using qota::CartesianMapping;
using qota::Mesh;
using qota::Point2;
using qota::detail::TriangleCorners;

// A mesh's triangles and plane points, as the proof takes them (the mesh's triangles are
// counter-clockwise seen from above).
struct Plane {
  std::vector<TriangleCorners> triangles;
  std::vector<Point2> vertices;
};
Plane planeOf(const Mesh& m) {
  Plane p;
  for (const auto& v : m.vertices) p.vertices.push_back({v.x(), v.y()});
  for (std::size_t t = 0; t < m.polygonCount(); ++t) {
    const auto c = m.polygon(t);
    p.triangles.push_back({{c[0], c[1], c[2]}, static_cast<std::uint32_t>(t)});
  }
  return p;
}
bool oneSheet(const Mesh& m, std::span<const std::uint8_t> left = {}) {
  const Plane p = planeOf(m);
  return qota::detail::oneSheet(p.triangles, p.vertices, left);
}

// A mesh of the points and triangles (corners counter-clockwise seen from above).
Mesh meshOf(const std::vector<Eigen::Vector3d>& points, std::initializer_list<std::array<std::uint32_t, 3>> triangles) {
  Mesh m;
  m.vertices = points;
  for (const auto& t : triangles) m.addTriangle(t[0], t[1], t[2]);
  return m;
}

// n x n cells of a grid with each vertex moved at random within a fifth of a cell, two
// triangles a cell (counter-clockwise): a proper triangulation.
Mesh jitteredGrid(int n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> jitter(-0.2, 0.2), height(0, 5);
  Mesh m;
  for (int r = 0; r <= n; ++r) {
    for (int c = 0; c <= n; ++c) m.addVertex({c + jitter(rng), r + jitter(rng), height(rng)});
  }
  const auto at = [n](int c, int r) { return static_cast<std::uint32_t>(r * (n + 1) + c); };
  for (int r = 0; r < n; ++r) {
    for (int c = 0; c < n; ++c) {
      m.addTriangle(at(c, r), at(c + 1, r), at(c + 1, r + 1));
      m.addTriangle(at(c, r), at(c + 1, r + 1), at(c, r + 1));
    }
  }
  return m;
}

// A ramp round the origin, `segments` steps of 15 degrees, rising 2 m a radian, its inner edge
// at 5 + 0.3 theta and 4 wide: past one turn (24 steps) its second turn lies over the first.
Mesh ramp(int segments) {
  Mesh m;
  for (int i = 0; i <= segments; ++i) {
    const double theta = i * std::numbers::pi / 12, inner = 5 + 0.3 * theta, outer = inner + 4;
    m.addVertex({inner * std::cos(theta), inner * std::sin(theta), 2 * theta});
    m.addVertex({outer * std::cos(theta), outer * std::sin(theta), 2 * theta});
  }
  for (int i = 0; i < segments; ++i) {
    const auto in0 = static_cast<std::uint32_t>(2 * i), out0 = in0 + 1, in1 = in0 + 2, out1 = in0 + 3;
    m.addTriangle(in0, out0, out1);
    m.addTriangle(in0, out1, in1);
  }
  return m;
}

TEST(OneSheet, AProperTriangulationIsOneSheet) {
  for (std::uint64_t seed = 1; seed <= 5; ++seed) EXPECT_TRUE(oneSheet(jitteredGrid(12, seed))) << seed;
  EXPECT_TRUE(oneSheet(ramp(21)));  // a C, 315 degrees round
}

TEST(OneSheet, ARampPastOneTurnIsNot) {
  // Its boundary crosses itself: the second turn's inner edge runs over the first step's end.
  EXPECT_FALSE(oneSheet(ramp(30)));
  EXPECT_FALSE(oneSheet(ramp(36)));
  EXPECT_FALSE(oneSheet(ramp(60)));
}

TEST(OneSheet, HolesIslandsAndPartsApartAreOneSheet) {
  const Mesh grid = jitteredGrid(6, 3);
  const std::size_t cell = 2 * (3 * 6 + 3);  // the first triangle of cell (3, 3)
  std::vector<std::uint8_t> left(grid.polygonCount(), 0);
  left[cell] = 1;  // a triangle inside: a hole, a clockwise loop inside the outer one
  EXPECT_TRUE(oneSheet(grid, left));
  left[cell + 1] = 1;  // the whole cell
  EXPECT_TRUE(oneSheet(grid, left));
  std::fill(left.begin(), left.end(), 0);
  left[1] = 1;  // a corner's triangle
  EXPECT_TRUE(oneSheet(grid, left));
  std::fill(left.begin(), left.end(), 0);
  left[cell] = left[cell - 2 * 6 - 1] = 1;  // two triangles meeting at a corner: a pinched hole
  EXPECT_TRUE(oneSheet(grid, left));
  std::fill(left.begin(), left.end(), 0);
  left[2 * 1 + 1] = 1;  // cell (1, 0)'s upper triangle: a hole touching the outer edge at a corner
  EXPECT_TRUE(oneSheet(grid, left));
  // Cells gone along a diagonal: voids meeting at corners, as a raster's do.
  std::fill(left.begin(), left.end(), 0);
  for (int k = 1; k < 5; ++k) left[2 * (k * 6 + k)] = left[2 * (k * 6 + k) + 1] = 1;
  EXPECT_TRUE(oneSheet(grid, left));
  // Every other cell of a 4 x 4 block gone, as a checkerboard: cells inside it are islands held
  // by their corners alone, each corner touching other loops.
  std::fill(left.begin(), left.end(), 0);
  for (int r = 1; r < 5; ++r) {
    for (int c = 1; c < 5; ++c) {
      if ((r + c) % 2 == 0) left[2 * (r * 6 + c)] = left[2 * (r * 6 + c) + 1] = 1;
    }
  }
  EXPECT_TRUE(oneSheet(grid, left));

  // A small triangle of its own over the cell's middle: an island in the cell's hole, a part
  // over the sheet where the cell is there.
  Mesh island = grid;
  const auto a = island.addVertex({3.45, 3.45, 9}), b = island.addVertex({3.55, 3.45, 9}),
             c = island.addVertex({3.5, 3.55, 9});
  island.addTriangle(a, b, c);
  std::vector<std::uint8_t> holed(island.polygonCount(), 0);
  holed[cell] = holed[cell + 1] = 1;
  EXPECT_TRUE(oneSheet(island, holed));
  EXPECT_FALSE(oneSheet(island));  // over the sheet: counted twice there

  // A ring of 3 x 3 cells (its middle cell gone) whose hole reaches its leftmost vertex, where
  // the hole's loop and the outer one touch: alone it is one sheet; laid over the grid it is
  // counted twice there (the loops must be taken apart at that touch to tell which way each
  // winds).
  const auto ring = [](double x0, double y0) {
    Mesh m;
    for (int r = 0; r < 4; ++r) {
      for (int c = 0; c < 4; ++c) m.addVertex({x0 + c - (c == 0 && r == 1 ? 0.5 : 0), y0 + r, 9});
    }
    const auto at = [](int c, int r) { return static_cast<std::uint32_t>(r * 4 + c); };
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) {
        if (r == 1 && c == 1) continue;
        if (!(r == 1 && c == 0)) m.addTriangle(at(c, r), at(c + 1, r), at(c + 1, r + 1));
        m.addTriangle(at(c, r), at(c + 1, r + 1), at(c, r + 1));
      }
    }
    return m;
  };
  EXPECT_TRUE(oneSheet(ring(0, 0)));
  Mesh ringOver = grid;
  const Mesh lifted = ring(1.5, 1.5);
  const auto base = static_cast<std::uint32_t>(ringOver.vertices.size());
  ringOver.vertices.insert(ringOver.vertices.end(), lifted.vertices.begin(), lifted.vertices.end());
  for (std::size_t t = 0; t < lifted.polygonCount(); ++t) {
    const auto k = lifted.polygon(t);
    ringOver.addTriangle(base + k[0], base + k[1], base + k[2]);
  }
  EXPECT_FALSE(oneSheet(ringOver));

  const std::vector<Eigen::Vector3d> six{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {5, 0, 0}, {6, 0, 0}, {5, 1, 0}};
  EXPECT_TRUE(oneSheet(meshOf(six, {{0, 1, 2}, {3, 4, 5}})));  // two triangles apart
  EXPECT_TRUE(oneSheet(meshOf(six, {{0, 1, 2}})));
}

TEST(OneSheet, TwinsTouchesAndOverlapsAtACornerAreLeftToThePairs) {
  const std::vector<Eigen::Vector3d> bow{{0, 0, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}, {-1, -1, 0}};
  // Two triangles sharing a corner only (a bow tie): one sheet, pinched there.
  EXPECT_TRUE(oneSheet(meshOf(bow, {{0, 1, 2}, {0, 3, 4}})));
  // Two sharing a corner, one within the other's angle there: round the corner two boundary
  // edges leave one after the other (the second triangle's covered corner lies in the first's).
  const std::vector<Eigen::Vector3d> fan{{0, 0, 0}, {2, 0, 0}, {0, 2, 0}, {2, 1, 0}, {1, 2, 0}};
  EXPECT_FALSE(oneSheet(meshOf(fan, {{0, 1, 2}, {0, 3, 4}})));
  // The same triangle twice: its edges each used twice the same way.
  EXPECT_FALSE(oneSheet(meshOf(bow, {{0, 1, 2}, {0, 1, 2}})));
  // Two triangles on one place with vertices of their own: two loops along each other.
  std::vector<Eigen::Vector3d> stacked = bow;
  for (int k = 0; k < 3; ++k) stacked.push_back(bow[k] + Eigen::Vector3d(0, 0, 1));
  EXPECT_FALSE(oneSheet(meshOf(stacked, {{0, 1, 2}, {5, 6, 7}})));
  // A ring of 8 cells round a missing centre, cut open beside one cell: that cell's corners on
  // the cut are vertices of their own at the places of its neighbours', so the boundary runs
  // along itself there. No two triangles overlap, but the proof does not take a boundary that
  // touches itself.
  Mesh ring;
  const auto vertex = [&](double x, double y) { return ring.addVertex({x, y, 0}); };
  std::uint32_t g[4][4];
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) g[r][c] = vertex(c, r);
  }
  const std::uint32_t cut0 = vertex(1, 0), cut1 = vertex(1, 1);  // the second side of the cut
  const auto cell = [&](std::uint32_t a, std::uint32_t b, std::uint32_t c, std::uint32_t d) {
    ring.addTriangle(a, b, c);  // a b c d counter-clockwise
    ring.addTriangle(a, c, d);
  };
  cell(g[0][0], cut0, cut1, g[1][0]);  // the cell left of the cut, on the cut's second side
  cell(g[0][1], g[0][2], g[1][2], g[1][1]);
  cell(g[0][2], g[0][3], g[1][3], g[1][2]);
  cell(g[1][2], g[1][3], g[2][3], g[2][2]);
  cell(g[2][2], g[2][3], g[3][3], g[3][2]);
  cell(g[2][1], g[2][2], g[3][2], g[3][1]);
  cell(g[2][0], g[2][1], g[3][1], g[3][0]);
  cell(g[1][0], g[1][1], g[2][1], g[2][0]);
  EXPECT_FALSE(oneSheet(ring));
}

TEST(OneSheet, InputsOutsideItsRulesAreLeftToThePairs) {
  const std::vector<Eigen::Vector3d> three{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  const Plane p = planeOf(meshOf(three, {{0, 1, 2}}));
  EXPECT_TRUE(qota::detail::oneSheet(p.triangles, p.vertices));
  std::vector<TriangleCorners> beyond = p.triangles;
  beyond[0].corner[2] = 3;  // a corner out of range
  EXPECT_FALSE(qota::detail::oneSheet(beyond, p.vertices));
  const std::vector<std::uint8_t> shortLeft(2, 0);  // a mask for another mesh
  EXPECT_FALSE(qota::detail::oneSheet(p.triangles, p.vertices, shortLeft));
  // Coordinates the exact orientations do not cover (and a range too narrow for its cells'
  // scale): false, not a guess.
  for (const double tiny : {1e-320, 1e-200}) {
    EXPECT_FALSE(oneSheet(meshOf({{0, 0, 0}, {tiny, 0, 0}, {0, 1, 0}}, {{0, 1, 2}}))) << tiny;
  }
  EXPECT_FALSE(oneSheet(meshOf({{0, 0, 0}, {1e200, 0, 0}, {0, 1, 0}}, {{0, 1, 2}})));
  // A fan of many triangles round one vertex (each edge's reverse is found by a search).
  Mesh fan;
  fan.addVertex({0, 0, 0});
  constexpr int kSpokes = 20000;
  for (int k = 0; k < kSpokes; ++k) {
    const double a = 2 * std::numbers::pi * k / kSpokes;
    fan.addVertex({std::cos(a), std::sin(a), 0});
  }
  for (std::uint32_t k = 1; k <= kSpokes; ++k) fan.addTriangle(0, k, k % kSpokes + 1);
  EXPECT_TRUE(oneSheet(fan));
}

// heightBelow and above at random points of the mesh's box, at random heights, against the
// oracle (points within 1e-9 of an edge, and height ties, skipped). Returns the points checked
// under two or more triangles.
int checkAgainstOracle(const Mesh& mesh, std::uint64_t seed) {
  const CartesianIndex index(mesh, CartesianMapping());
  Eigen::Vector3d lo = mesh.vertices[0], hi = mesh.vertices[0];
  for (const auto& v : mesh.vertices) lo = lo.cwiseMin(v), hi = hi.cwiseMax(v);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0, 1);
  int layered = 0;
  for (int q = 0; q < 4000; ++q) {
    const Eigen::Vector3d p = lo + (hi - lo).cwiseProduct(Eigen::Vector3d(unit(rng), unit(rng), unit(rng)));
    const auto oracle = qota::test::bruteForce(mesh, CartesianMapping().gravity(), CartesianMapping().origin(), p);
    if (oracle.nearestEdge < 1e-9) continue;
    std::optional<double> below, above;
    for (const auto& h : oracle.hits) {
      if (h.height <= p.z() && (!below || h.height > *below)) below = h.height;
      if (h.height >= p.z() && (!above || h.height < *above)) above = h.height;
    }
    layered += oracle.hits.size() > 1;
    const auto gotBelow = index.heightBelow(p.x(), p.y(), p.z());
    const auto gotAbove = index.above(p.x(), p.y(), p.z());
    EXPECT_EQ(gotBelow.has_value(), below.has_value()) << p.transpose();
    EXPECT_EQ(gotAbove.has_value(), above.has_value()) << p.transpose();
    if (below && gotBelow) {
      EXPECT_NEAR(*gotBelow, *below, 1e-9) << p.transpose();
    }
    if (above && gotAbove) {
      EXPECT_NEAR(gotAbove->height, *above, 1e-9) << p.transpose();
    }
  }
  return layered;
}

TEST(OneSheet, IndexesOverSheetsAndOverARampAnswerAsTheOracle) {
  EXPECT_EQ(checkAgainstOracle(jitteredGrid(40, 7), 1), 0);
  // Holes of a cell each, every third with an island in it (one sheet), and islands over the
  // sheet beside them (not: the pairs decide there).
  const Mesh grid = jitteredGrid(40, 8);
  Mesh holed;
  holed.vertices = grid.vertices;
  for (std::size_t t = 0; t < grid.polygonCount(); ++t) {
    const std::size_t cell = t / 2, c = cell % 40, r = cell / 40;
    if (c % 5 == 2 && r % 5 == 2) continue;
    const auto k = grid.polygon(t);
    holed.addTriangle(k[0], k[1], k[2]);
  }
  Mesh over = holed;
  for (int r = 2; r < 40; r += 5) {
    for (int c = 2; c < 40; c += 15) {
      for (Mesh* m : {&holed, &over}) {
        const double x = c + (m == &holed ? 0.5 : 2.5), y = r + 0.5;
        const auto a = m->addVertex({x - 0.1, y - 0.1, 9}), b = m->addVertex({x + 0.1, y - 0.1, 9}),
                   d = m->addVertex({x, y + 0.1, 9});
        m->addTriangle(a, b, d);
      }
    }
  }
  EXPECT_TRUE(oneSheet(holed));
  EXPECT_FALSE(oneSheet(over));
  EXPECT_EQ(checkAgainstOracle(holed, 4), 0);
  checkAgainstOracle(over, 5);
  // A checkerboard of voids in a block of 10 x 10 cells: pinches, and islands held by corners.
  Mesh checkered;
  checkered.vertices = grid.vertices;
  for (std::size_t t = 0; t < grid.polygonCount(); ++t) {
    const std::size_t cell = t / 2, c = cell % 40, r = cell / 40;
    if (c >= 10 && c < 20 && r >= 10 && r < 20 && (c + r) % 2 == 0) continue;
    const auto k = grid.polygon(t);
    checkered.addTriangle(k[0], k[1], k[2]);
  }
  EXPECT_TRUE(oneSheet(checkered));
  EXPECT_EQ(checkAgainstOracle(checkered, 7), 0);
  // Two triangles sharing a corner, the second over the first near it (a pinch that overlaps).
  const Mesh fan = meshOf({{0, 0, 0}, {20, 0, 0}, {0, 20, 0}, {20, 10, 5}, {10, 20, 5}}, {{0, 1, 2}, {0, 3, 4}});
  EXPECT_GT(checkAgainstOracle(fan, 6), 300);
  EXPECT_EQ(checkAgainstOracle(ramp(21), 2), 0);
  // Two and a half turns: points under two and three floors, which a leaf taken for a single
  // layer would answer by its first triangle (the lowest floor).
  EXPECT_GT(checkAgainstOracle(ramp(60), 3), 300);
}

TEST(OneSheet, EveryLeafOfASheetIsASingleLayerInPolygonOrder) {
  const Mesh mesh = jitteredGrid(60, 11);
  const CartesianIndex index(mesh, CartesianMapping());
  ASSERT_FALSE(index.gridFastPath());
  int leaves = 0;
  index.tree().forEachLeaf([&](const qota::Quadtree::Node& leaf, std::uint32_t) {
    const auto items = index.tree().leafRange(leaf);
    if (items.size() < 2) return;
    ++leaves;
    EXPECT_TRUE(qota::Quadtree::singleLayer(leaf));
  });
  EXPECT_GT(leaves, 100);
}

}  // namespace
