// The planar index's regular-grid fast path (an implementation detail of terrain.hpp): on a
// terrain whose vertices form a w x h lattice and whose triangles are the raster rule's
// (raster_grid.hpp: two per cell, split from corner (col, row) to (col + 1, row + 1)), the
// triangle under a point is found by arithmetic (its cell, then which half) instead of by the
// quadtree. This class owns the grid's tables and that arithmetic: recognising the grid in a
// triangle list (each triangle checked against the raster rule, RasterGrid::innerTriangleWith:
// the rule is written there only), the cell and half of a point, each slot's triangle, and where
// a half's corners sit. The index (PlanarCore) keeps the plane arithmetic and decides when to
// use the path.
//
// Slots: the raster rule's inner triangle numbers (RasterGrid::innerTriangle), half 0 being the
// triangle with corner (col, row + 1).
// A lean grid stores every half's corners at the same offsets from the cell's first vertex, so
// a query reads the corners straight from the vertex arrays (and keeps no triangle records).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <span>
#include <vector>

#include "qota/memory.hpp"
#include "qota/raster_grid.hpp"
#include "qota/vocabulary.hpp"

namespace qota {
struct TreeFileAccess;  // the on-disk format (treefile.cpp) reads and writes the shape and slots
}

namespace qota::detail {

// A triangle of the index by its mapped vertex indices (counter-clockwise) and source polygon.
struct TriangleCorners {
  std::uint32_t corner[3];
  std::uint32_t polygon;
};

class GridPath {
 public:
  // Whether the triangles over the vertices `corners` form a regular grid, vertex i at lattice
  // (i % w, i / w), every triangle one half of a cell, each half once, and the vertices on an
  // affine lattice to within 1e-6 of a cell. If so, sets the grid's shape and returns each
  // triangle's slot; else returns nothing and leaves the path off.
  std::vector<std::uint32_t> recognise(std::span<const Point2> corners, std::span<const TriangleCorners> triangles);
  // recognise's test of the vertices alone, for triangles known to be the raster rule's (an
  // index built from a GridMesh): whether the nw x nh vertices lie on an affine lattice (as
  // above); if so, sets the grid's shape.
  bool fitLattice(std::span<const Point2> corners, std::uint64_t nw, std::uint64_t nh);
  // The slots' triangles once the index has ordered them: triangle t sits in slot slots[t].
  void fillSlots(std::span<const std::uint64_t> slotThenTriangle);
  // (Re)derives the lean tables from the triangles, vertices and heights (after recognise, or
  // after a tree file gave the shape and slots).
  void setUpLean(std::span<const TriangleCorners> triangles, std::span<const Point2> corners,
                 std::span<const double> heights);
  // A lean grid straight from a lattice of mapped vertices with no index around it (a raster
  // sampler's tile): the tables setUpLean derives for the raster rule's triangles over nw x nh
  // vertices, a slot present where its three corners have heights (not NaN). The same tables,
  // path and answers as an index built from that grid (GridMesh) has, with no slot's triangle
  // (cellTri stays empty). False, and the path off, where the vertices are no affine lattice.
  bool setUpLattice(std::uint64_t nw, std::uint64_t nh, std::span<const Point2> corners,
                    std::span<const double> heights);
  // The lean grid's fast answers, the index's own (PlanarCore::heightsBelowBatch): out[i] the
  // height at points[i] where it lies clearly inside a present triangle whose plane needs no
  // check (decided[i] = kHeight); no terrain where it lies clearly inside a slot without one
  // (kNoTerrain: the index's exact path finds none there); else kUndecided, for the caller's
  // exact path. corners and heights are the vertices' mapped (u, v) and h (read where the lean
  // tables do not hold them).
  static constexpr std::uint8_t kUndecided = 0, kHeight = 1, kNoTerrain = 2;
  void leanHeights(std::span<const Point2> corners, std::span<const double> heights, std::span<const Point2> points,
                   double* out, std::uint8_t* decided) const;
  // A removed triangle leaves its slot.
  void clearSlot(const TriangleCorners& triangle, std::uint32_t t);
  // Off for good (an inserted polygon may overlap the grid).
  void turnOff();

  bool on() const { return w != 0; }
  // Whether the lean tables answer (setUpLean, setUpLattice): the corners are read from the
  // vertex arrays or the lattice's axes, with no triangle records.
  bool isLean() const { return lean; }
  // Whether a lean answer reads the vertices' (u, v) and heights from the caller's arrays (else
  // the lattice's axes and float heights hold them, and the caller may drop its arrays).
  bool readsVertexCoordinates() const { return colU.empty(); }
  bool readsVertexHeights() const { return h32.empty(); }
  std::size_t memoryBytes() const {
    return cellTri.size() * sizeof(std::uint32_t) + h32.size() * sizeof(float) +
           (colU.size() + rowV.size()) * sizeof(double) + presentBits.size() * sizeof(std::uint64_t);
  }

  // Where (u, v) falls: its cell and half, and whether it is clearly inside that half's
  // triangle (farther than 1e-5 cell from its sides); inGrid false off the cells (and for NaN).
  // fc and fr are set in every case (the near-edge search starts from them).
  struct Cell {
    double fc, fr;  // column and row, fractional
    bool inGrid, clear;
    std::uint64_t col, row, slot;
    std::uint32_t half;
  };
  [[gnu::always_inline]] Cell cell(double u, double v) const;
  bool slotPresent(std::uint64_t slot) const {
    return presentBits.empty() || ((presentBits[slot >> 6] >> (slot & 63)) & 1);
  }
  // The index's triangle in a slot (kNoTriangle: none), for a grid built from triangles.
  std::uint32_t triangleIn(std::uint64_t slot) const { return cellTri[slot]; }
  // Every triangle that may hold a point at fractional column and row (fc, fr) which is not
  // clearly inside its cell's half: on or near an edge (a pixel centre, a cell side), in a hole,
  // or just off the grid. They lie in the estimated cell or a neighbour across a side the point
  // is within 1e-5 cell of (the vertices lie on the affine grid to within 1e-6 of a cell);
  // nothing beyond a cell off the grid (NaN included). Calls visit(t) for each.
  template <class Visit>
  void forTrianglesNear(double fc, double fr, Visit&& visit) const;
  // Corner k of the triangle in half `half` of cell (col, row) on a lean grid: its mapped (u, v)
  // and height, from the lattice's axes and float heights when exact, else from the vertices.
  [[gnu::always_inline]] void leanCorner(std::uint64_t col, std::uint64_t row, std::uint32_t half, int k,
                                         std::span<const Point2> corners, std::span<const double> heights, double& u,
                                         double& v, double& h) const;
  // Asks for the cache lines a lean answer in cell c reads (a batch overlaps their misses).
  [[gnu::always_inline]] void prefetchLean(const Cell& c, std::span<const Point2> corners,
                                           std::span<const double> heights) const;
  // Asks for the line of the slot table that holds cell c's two triangles.
  void prefetchSlots(const Cell& c) const { __builtin_prefetch(&cellTri[slotOf(c.col, c.row, 0)]); }
  // The slot of half `half` of cell (col, row).
  std::uint64_t slotOf(std::uint64_t col, std::uint64_t row, std::uint32_t half) const {
    return RasterGrid::innerTriangle(w, row, col, half);
  }

 private:
  friend struct qota::TreeFileAccess;
  // The shape: w x h vertices (w == 0: no grid), the inverse of the affine map (col, row) ->
  // (u, v) about vertex 0, and per slot its triangle (kNoTriangle where the terrain has none).
  std::uint32_t w = 0, h = 0;
  double u0 = 0, v0 = 0, inv[4] = {0, 0, 0, 0};
  double cellsU = 0, cellsV = 0;  // w - 1, h - 1
  BigVector<std::uint32_t> cellTri;
  // The lean tables: per half and corner, the offset from the cell's first vertex and its column
  // and row offsets (0 or 1); u per column and v per row when the vertices are exactly those
  // (else empty); heights as floats when exact (else empty); one bit per slot that holds a
  // triangle (empty: all do).
  bool lean = false;
  bool axesF32 = false;  // colU and h32 both in use: the common DEM
  std::uint32_t cornerOffset[2][3] = {{0, 0, 0}, {0, 0, 0}};
  std::uint8_t dc[2][3] = {}, dr[2][3] = {};
  std::vector<double> colU, rowV;
  BigVector<float> h32;
  std::vector<std::uint64_t> presentBits;

  // setUpLean's and setUpLattice's common part, once the corners' offsets are known.
  void setUpTables(std::span<const Point2> corners, std::span<const double> heights);
};

[[gnu::always_inline]] inline GridPath::Cell GridPath::cell(double u, double v) const {
  Cell g{};
  const double du = u - u0, dv = v - v0;
  g.fc = inv[0] * du + inv[1] * dv, g.fr = inv[2] * du + inv[3] * dv;
  g.inGrid = g.fc >= 0 && g.fr >= 0 && g.fc < cellsU && g.fr < cellsV;
  if (!g.inGrid) return g;  // also NaN
  // Signed conversions: in range here, and without the unsigned one's branch.
  const auto col = static_cast<std::int64_t>(g.fc), row = static_cast<std::int64_t>(g.fr);
  g.col = static_cast<std::uint64_t>(col), g.row = static_cast<std::uint64_t>(row);
  // The half of the cell with corner (col, row + 1) lies where the row fraction exceeds the
  // column fraction.
  const double xc = g.fc - static_cast<double>(col), xr = g.fr - static_cast<double>(row);
  g.half = xr > xc ? 0 : 1;
  g.slot = slotOf(g.col, g.row, g.half);
  // Clearly inside: farther than 1e-5 cell from the half's sides, with the vertices within 1e-6
  // cell of their grid positions (recognise), so no other triangle can hold the point.
  g.clear = std::min(std::min(std::min(xc, xr), 1 - std::max(xc, xr)), std::fabs(xr - xc)) > 1e-5;
  return g;
}

[[gnu::always_inline]] inline void GridPath::leanCorner(std::uint64_t col, std::uint64_t row, std::uint32_t half, int k,
                                                        std::span<const Point2> corners,
                                                        std::span<const double> heights, double& u, double& v,
                                                        double& h) const {
  const std::uint64_t x = row * w + col + cornerOffset[half][k];
  if (axesF32) [[likely]] {  // the common DEM
    u = colU[col + dc[half][k]], v = rowV[row + dr[half][k]];
    h = static_cast<double>(h32[x]);
    return;
  }
  if (colU.empty()) {
    u = corners[x].u, v = corners[x].v;
  } else {
    u = colU[col + dc[half][k]], v = rowV[row + dr[half][k]];
  }
  h = h32.empty() ? heights[x] : static_cast<double>(h32[x]);
}

template <class Visit>
void GridPath::forTrianglesNear(double fc, double fr, Visit&& visit) const {
  if (!(fc >= -1 && fr >= -1 && fc <= w && fr <= h)) return;
  const auto col = static_cast<std::int64_t>(std::floor(std::clamp(fc, 0.0, cellsU - 0.5)));
  const auto row = static_cast<std::int64_t>(std::floor(std::clamp(fr, 0.0, cellsV - 0.5)));
  constexpr double kNear = 1e-5;
  const std::int64_t c0 = col - (fc - col < kNear), c1 = col + (col + 1 - fc < kNear);
  const std::int64_t r0 = row - (fr - row < kNear), r1 = row + (row + 1 - fr < kNear);
  for (std::int64_t r = std::max<std::int64_t>(r0, 0); r <= std::min<std::int64_t>(r1, h - 2); ++r) {
    for (std::int64_t c = std::max<std::int64_t>(c0, 0); c <= std::min<std::int64_t>(c1, w - 2); ++c) {
      for (std::uint32_t half = 0; half < 2; ++half) {
        const std::uint32_t t = cellTri[slotOf(c, r, half)];
        if (t != kNoTriangle) visit(t);
      }
    }
  }
}

[[gnu::always_inline]] inline void GridPath::prefetchLean(const Cell& c, std::span<const Point2> corners,
                                                          std::span<const double> heights) const {
  const std::uint64_t x = c.row * w + c.col;
  if (!presentBits.empty()) __builtin_prefetch(&presentBits[c.slot >> 6]);
  if (!h32.empty()) {
    __builtin_prefetch(&h32[x]), __builtin_prefetch(&h32[x + 1]);
    __builtin_prefetch(&h32[x + w]), __builtin_prefetch(&h32[x + w + 1]);
  } else {
    __builtin_prefetch(&heights[x]), __builtin_prefetch(&heights[x + 1]);
    __builtin_prefetch(&heights[x + w]), __builtin_prefetch(&heights[x + w + 1]);
  }
  if (colU.empty()) __builtin_prefetch(&corners[x]), __builtin_prefetch(&corners[x + w + 1]);
}

}  // namespace qota::detail
