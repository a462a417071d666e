#include "qota/grid_path.hpp"

#include <algorithm>
#include <array>

#include "qota/predicates.hpp"
#include "qota/raster_grid.hpp"

namespace qota::detail {

std::vector<std::uint32_t> GridPath::recognise(std::span<const Point2> corners,
                                               std::span<const TriangleCorners> pending) {
  // A regular grid of w x h vertices whose triangles are the raster rule's inner ones
  // (raster_grid.hpp: two a cell, split along the diagonal from vertex x to x + w + 1), each
  // once: w from the first triangle, then every triangle must be the rule's. A slot is the
  // rule's inner triangle number, 2 * cell + half (half 0 has corner x + w). Returns each
  // triangle's slot, or nothing when the mesh is not such a grid.
  const std::size_t nv = corners.size();
  if (pending.empty()) return {};
  auto sorted = [](const TriangleCorners& q) {
    std::array<std::uint32_t, 3> k{q.corner[0], q.corner[1], q.corner[2]};
    std::sort(k.begin(), k.end());
    return k;
  };
  const auto k0 = sorted(pending[0]);
  // The lattice width from the first triangle (its smallest and largest corners are x, x + w + 1).
  const std::uint64_t nw = k0[2] - k0[0] - 1;
  if (nw < 2 || nv % nw != 0 || nv / nw < 2) return {};
  const std::uint64_t nh = nv / nw;
  if (nw > 0xffffffffu || 2 * (nw - 1) * (nh - 1) >= 0xffffffffu) return {};
  const RasterGrid lattice(static_cast<int>(nw), static_cast<int>(nh), {});
  std::vector<std::uint8_t> taken(2 * (nw - 1) * (nh - 1), 0);
  std::vector<std::uint32_t> slots(pending.size());
  for (std::size_t t = 0; t < pending.size(); ++t) {
    const TriangleCorners& q = pending[t];
    const std::optional<std::uint64_t> found = lattice.innerTriangleWith(q.corner[0], q.corner[1], q.corner[2]);
    if (!found) return {};
    const std::uint64_t slot = *found;
    if (taken[slot]) return {};  // the same half twice: overlapping, not a grid
    taken[slot] = 1;
    slots[t] = static_cast<std::uint32_t>(slot);
  }
  if (!fitLattice(corners, nw, nh)) return {};
  return slots;
}

bool GridPath::fitLattice(std::span<const Point2> corners, std::uint64_t nw, std::uint64_t nh) {
  const std::size_t nv = corners.size();
  if (nw < 2 || nh < 2 || nv != nw * nh) return false;
  if (nw > 0xffffffffu || 2 * (nw - 1) * (nh - 1) >= 0xffffffffu) return false;
  // The vertices must lie on the affine grid (u, v) = o + col * a + row * b, to well within a
  // cell, so that the cell found by arithmetic is the cell (or a neighbour, near its edges).
  const Point2 o = corners[0], pa = corners[1], pb = corners[nw];
  const double au = pa.u - o.u, av = pa.v - o.v, bu = pb.u - o.u, bv = pb.v - o.v;
  const double det = au * bv - av * bu;
  if (!std::isfinite(det) || det == 0) return false;
  const double cellSize = std::min(std::hypot(au, av), std::hypot(bu, bv));
  const double tolerance = 1e-6 * cellSize, tolerance2 = tolerance * tolerance;
  // hypot(eu, ev) <= tolerance, decided by the squared distance where that is 2% or more from
  // the bound (hypot is within an ulp of the root, the square within a few), else by hypot: the
  // same decisions, without a library call per vertex.
  const bool squares = tolerance2 > 1e-290 && std::isfinite(tolerance2);
  // And within 1e-6 of their column and row as the query computes them (the fast path's
  // "clearly inside" margin of 1e-5 cell rests on this). Both tests a row at a time.
  const double inverse[4] = {bv / det, -bu / det, -av / det, au / det};
  for (std::uint64_t row = 0; row < nh; ++row) {
    const Point2* line = &corners[row * nw];
    const double r = static_cast<double>(row);
    for (std::uint64_t col = 0; col < nw; ++col) {
      const double c = static_cast<double>(col);
      const Point2 p = line[col];
      const double eu = o.u + c * au + r * bu - p.u, ev = o.v + c * av + r * bv - p.v;
      const double e2 = eu * eu + ev * ev;
      if (squares && e2 <= 0.98 * tolerance2) continue;
      if (squares && e2 >= 1.02 * tolerance2 && std::isfinite(e2)) return false;
      if (!(std::hypot(eu, ev) <= tolerance)) return false;
    }
  }
  for (std::uint64_t row = 0; row < nh; ++row) {
    const Point2* line = &corners[row * nw];
    const double r = static_cast<double>(row);
    for (std::uint64_t col = 0; col < nw; ++col) {
      const double du = line[col].u - o.u, dv = line[col].v - o.v;
      const double fc = inverse[0] * du + inverse[1] * dv, fr = inverse[2] * du + inverse[3] * dv;
      if (!(std::fabs(fc - static_cast<double>(col)) <= 1e-6 && std::fabs(fr - r) <= 1e-6)) return false;
    }
  }
  w = static_cast<std::uint32_t>(nw);
  h = static_cast<std::uint32_t>(nh);
  cellsU = w - 1.0, cellsV = h - 1.0;
  u0 = o.u, v0 = o.v;
  for (int k = 0; k < 4; ++k) inv[k] = inverse[k];
  return true;
}

void GridPath::fillSlots(std::span<const std::uint64_t> slotThenTriangle) {
  cellTri.assign(2ull * (w - 1) * (h - 1), kNoTriangle);
  for (std::size_t t = 0; t < slotThenTriangle.size(); ++t) {
    cellTri[slotThenTriangle[t] >> 32] = static_cast<std::uint32_t>(t);
  }
}

void GridPath::setUpLean(std::span<const TriangleCorners> triangles, std::span<const Point2> corners,
                         std::span<const double> heights) {
  lean = axesF32 = false;
  cellsU = w ? w - 1.0 : 0.0, cellsV = h ? h - 1.0 : 0.0;
  colU.clear(), rowV.clear(), presentBits.clear();
  BigVector<float>().swap(h32);
  // Each half of a cell stores its corners (after fanPolygon's orientation) at fixed offsets from
  // the cell's first vertex x = row * w + col: find them from the first triangle of each half and
  // check every triangle.
  bool seen[2] = {false, false};
  for (std::uint32_t slot = 0; slot < cellTri.size(); ++slot) {
    const std::uint32_t t = cellTri[slot];
    if (t == kNoTriangle) continue;
    const std::uint64_t cell = slot / 2, half = slot % 2;
    const std::uint64_t x = (cell / (w - 1)) * w + cell % (w - 1);
    for (int k = 0; k < 3; ++k) {
      const std::int64_t offset = static_cast<std::int64_t>(triangles[t].corner[k]) - static_cast<std::int64_t>(x);
      if (!seen[half]) {
        cornerOffset[half][k] = static_cast<std::uint32_t>(offset);
      } else if (cornerOffset[half][k] != static_cast<std::uint32_t>(offset)) {
        return;
      }
    }
    seen[half] = true;
  }
  for (int half = 0; half < 2; ++half) {
    for (int k = 0; k < 3; ++k) {
      const std::uint64_t off = cornerOffset[half][k];
      if (off != 0 && off != 1 && off != w && off != w + 1ull) return;
    }
  }
  lean = true;
  setUpTables(corners, heights);
  // Which slots hold a triangle, one bit each, unless every one does.
  if (std::find(cellTri.begin(), cellTri.end(), kNoTriangle) != cellTri.end()) {
    presentBits.assign((cellTri.size() + 63) / 64, 0);
    for (std::uint64_t slot = 0; slot < cellTri.size(); ++slot) {
      if (cellTri[slot] != kNoTriangle) presentBits[slot >> 6] |= std::uint64_t{1} << (slot & 63);
    }
  }
}

void GridPath::setUpTables(std::span<const Point2> corners, std::span<const double> heights) {
  for (int half = 0; half < 2; ++half) {
    for (int k = 0; k < 3; ++k) {
      dc[half][k] = static_cast<std::uint8_t>(cornerOffset[half][k] % w);
      dr[half][k] = static_cast<std::uint8_t>(cornerOffset[half][k] / w);
    }
  }
  // u by column and v by row, when the vertices' coordinates are exactly those (an axis-aligned
  // grid under a vertical gravity): then a query reads no vertex coordinates.
  std::vector<double> cols(w), rows(h);
  for (std::uint64_t c = 0; c < w; ++c) cols[c] = corners[c].u;
  for (std::uint64_t r = 0; r < h; ++r) rows[r] = corners[r * w].v;
  bool axes = corners.size() == static_cast<std::size_t>(w) * h;
  for (std::uint64_t r = 0; r < h && axes; ++r) {
    const Point2* line = &corners[r * w];
    for (std::uint64_t c = 0; c < w; ++c) axes = axes && line[c].u == cols[c] && line[c].v == rows[r];
  }
  if (axes) colU.swap(cols), rowV.swap(rows);
  // Heights in float when every one is exact in float (Int16 and Float32 rasters): half the bytes
  // a random query pulls through the cache. A NaN (a vertex without data) stays NaN in float, and
  // no present slot has it as a corner.
  bool exact = true;
  for (std::size_t i = 0; i < heights.size() && exact; ++i) {
    exact = static_cast<double>(static_cast<float>(heights[i])) == heights[i] || std::isnan(heights[i]);
  }
  if (exact) {
    h32.resize(heights.size());
    for (std::size_t i = 0; i < heights.size(); ++i) h32[i] = static_cast<float>(heights[i]);
  }
  axesF32 = !colU.empty() && !h32.empty();
}

bool GridPath::setUpLattice(std::uint64_t nw, std::uint64_t nh, std::span<const Point2> corners,
                            std::span<const double> heights) {
  turnOff();
  colU.clear(), rowV.clear(), presentBits.clear();
  BigVector<float>().swap(h32);
  if (heights.size() != corners.size() || !fitLattice(corners, nw, nh)) return false;  // (still off)
  cellsU = w - 1.0, cellsV = h - 1.0;
  // Every triangle turns as the first cell's of its half (the vertices lie within 1e-6 cell of
  // an affine lattice, so no triangle's exact orientation differs from its ideal one); the index
  // stores each counter-clockwise (PlanarCore::fanPolygon), which fixes the corners' offsets.
  const std::uint32_t W = w;
  const int turn[2] = {orient2dSign(corners[0], corners[W], corners[W + 1]),
                       orient2dSign(corners[0], corners[W + 1], corners[1])};
  if (turn[0] == 0 || turn[1] == 0) {
    turnOff();
    return false;
  }
  const std::uint32_t offsets[2][3] = {{0, W, W + 1}, {0, W + 1, 1}};
  for (int half = 0; half < 2; ++half) {
    cornerOffset[half][0] = 0;
    cornerOffset[half][1] = offsets[half][turn[half] > 0 ? 1 : 2];
    cornerOffset[half][2] = offsets[half][turn[half] > 0 ? 2 : 1];
  }
  lean = true;
  setUpTables(corners, heights);
  // A slot is present where its triangle's three corners have heights.
  const std::uint64_t slots = 2ull * (w - 1) * (h - 1);
  bool all = true;
  std::vector<std::uint64_t> bits((slots + 63) / 64, 0);
  for (std::uint64_t r = 0; r + 1 < h; ++r) {
    for (std::uint64_t c = 0; c + 1 < w; ++c) {
      const std::uint64_t x = r * w + c, slot = slotOf(c, r, 0);
      const bool tl = !std::isnan(heights[x]), tr = !std::isnan(heights[x + 1]);
      const bool bl = !std::isnan(heights[x + w]), br = !std::isnan(heights[x + w + 1]);
      const bool present[2] = {tl && bl && br, tl && br && tr};
      for (int half = 0; half < 2; ++half) {
        all = all && present[half];
        if (present[half]) bits[(slot + half) >> 6] |= std::uint64_t{1} << ((slot + half) & 63);
      }
    }
  }
  if (!all) presentBits.swap(bits);
  return true;
}

void GridPath::clearSlot(const TriangleCorners& triangle, std::uint32_t t) {
  const std::optional<std::uint64_t> found =
      RasterGrid(static_cast<int>(w), static_cast<int>(h), {})
          .innerTriangleWith(triangle.corner[0], triangle.corner[1], triangle.corner[2]);
  if (!found) return;
  const std::uint64_t slot = *found;
  if (slot < cellTri.size() && cellTri[slot] == t) {
    cellTri[slot] = kNoTriangle;
    if (lean) {
      if (presentBits.empty()) presentBits.assign((cellTri.size() + 63) / 64, ~std::uint64_t{0});
      presentBits[slot >> 6] &= ~(std::uint64_t{1} << (slot & 63));
    }
  }
}

void GridPath::turnOff() {
  w = h = 0;
  lean = axesF32 = false;
  BigVector<std::uint32_t>().swap(cellTri);
}

}  // namespace qota::detail
