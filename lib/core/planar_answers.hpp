// The planar index's hot answers (private to lib/core), inline for the single queries
// (planar_query.cpp) and the batches (planar_batch.cpp) alike: the lean grid's corners, plane
// and height, the grid answer with a cursor's memo, and the quadtree leaf's triangle tests.
// One definition compiled into both, so a batch answers what the single query does, bit for bit.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>

#include "float_bounds.hpp"
#include "planar_arith.hpp"
#include "qota/terrain.hpp"

namespace qota {

[[gnu::always_inline]] inline void PlanarCore::leanCorner(std::uint64_t col, std::uint64_t row, std::uint32_t half,
                                                          int k, double& u, double& v, double& h) const {
  grid_.leanCorner(col, row, half, k, corners2_, cornerH_, u, v, h);
}

// The height at (u, v) on the triangle in half `half` of cell (col, row), and its plane: the
// records' arithmetic (cornerPlane, then leanHeight's clamp), without cornerPlane's checks and the
// clamp where they change nothing: finite slopes of an up-facing plane (nh > 0) give a finite
// height, slopes that are not finite give none, so nh > 0 and a height within the corners' range
// stand for all of them.
[[gnu::always_inline]] inline double PlanarCore::leanAnswer(std::uint64_t col, std::uint64_t row, std::uint32_t half,
                                                            double u, double v, LeanPlane& p) const {
  double u0, v0, h0, u1, v1, h1, u2, v2, h2;
  leanCorner(col, row, half, 0, u0, v0, h0);
  leanCorner(col, row, half, 1, u1, v1, h1);
  leanCorner(col, row, half, 2, u2, v2, h2);
  const planar::RawSlopes r = planar::rawSlopes(u0, v0, h0, u1, v1, h1, u2, v2, h2);
  p = {r.a, r.b, h0, u0, v0, std::min(h0, std::min(h1, h2)), std::max(h0, std::max(h1, h2))};
  const double h = h0 + r.a * (u - u0) + r.b * (v - v0);
  if (r.nh > 0 && h >= p.lo && h <= p.hi) [[likely]]
    return h;
  // A sliver, or a height the clamp may move: the checked plane.
  const planar::PlaneFit f = planar::cornerPlane(u0, v0, h0, u1, v1, h1, u2, v2, h2);
  p.a = f.a, p.b = f.b, p.h0 = f.h0;
  return leanHeight(p, u, v);
}

// heightOf's expression on the record the same corners make. The clamp to the corners' height
// range rounded outward to floats changes nothing for a value inside the range itself, the common
// case.
[[gnu::always_inline]] inline double PlanarCore::leanHeight(const LeanPlane& p, double u, double v) {
  const double h = p.h0 + p.a * (u - p.u0) + p.b * (v - p.v0);
  if (h >= p.lo && h <= p.hi) [[likely]]
    return h;
  return std::clamp(h, static_cast<double>(floatBelow(p.lo)), static_cast<double>(floatAbove(p.hi)));
}

template <bool NeedId>
[[gnu::always_inline]] inline std::uint32_t PlanarCore::gridAnswer(double u, double v, double& h,
                                                                   Cursor* cursor) const {
  if (grid_.isLean()) {
    const detail::GridPath::Cell g = grid_.cell(u, v);
    if (g.inGrid && g.clear) [[likely]] {
      const std::uint64_t slot = g.slot;
      if (cursor && cursor->memo.key == slot && cursor->memo.owner == this && cursor->memo.generation == generation_) {
        const double* m = cursor->memo.value;
        h = leanHeight({m[0], m[1], m[2], m[3], m[4], m[5], m[6]}, u, v);
        return NeedId ? cursor->memo.item : kFound;
      }
      std::uint32_t t = kFound;
      bool present;
      if constexpr (NeedId) {
        t = grid_.triangleIn(slot);
        present = t != kNoTriangle;
      } else {
        present = grid_.slotPresent(slot);
      }
      if (present) [[likely]] {
        LeanPlane p;
        h = leanAnswer(g.col, g.row, g.half, u, v, p);
        if (cursor) {
          auto& m = cursor->memo;
          m.owner = this, m.generation = generation_, m.key = slot;
          m.item = NeedId ? t : grid_.triangleIn(slot);
          // One store each: a copy through a local array made the compiler store it in halves and
          // reload it whole, a store-forwarding stall on every query of a walk.
          m.value[0] = p.a, m.value[1] = p.b, m.value[2] = p.h0, m.value[3] = p.u0;
          m.value[4] = p.v0, m.value[5] = p.lo, m.value[6] = p.hi;
        }
        return t;
      }
    }
    return gridAnswerNearEdge(u, v, g.fc, g.fr, h);
  }
  return gridAnswerFromRecords(u, v, h);
}

inline double PlanarCore::heightOf(const Tri& t, double u, double v) const {
  // The clamp keeps a sliver's extrapolated plane inside its corners' height range.
  return std::clamp(t.h0 + t.a * (u - t.u0) + t.b * (v - t.v0), static_cast<double>(t.hlo), static_cast<double>(t.hhi));
}

inline void PlanarCore::prefetchTriangles(std::span<const std::uint32_t> items) const {
  for (std::uint32_t t : items) {
    const char* p = reinterpret_cast<const char*>(&tris_[t]);
    __builtin_prefetch(p);
    __builtin_prefetch(p + 64);
  }
}

inline double PlanarCore::smallestEdge(const Tri& r, double u, double v) {
  const double e0 = r.A[0] * u + r.B[0] * v + r.C[0];
  const double e1 = r.A[1] * u + r.B[1] * v + r.C[1];
  const double e2 = r.A[2] * u + r.B[2] * v + r.C[2];
  return std::min(e0, std::min(e1, e2));
}

inline bool PlanarCore::contains(const Tri& r, std::uint32_t t, double u, double v) const {
  const double m = smallestEdge(r, u, v);
  if (std::fabs(m) <= r.tol) [[unlikely]]
    return inside(t, u, v);
  return m > 0;
}

template <bool Below>
std::uint32_t PlanarCore::nearestIn(std::span<const std::uint32_t> items, bool singleLayer, double u, double v,
                                    double z, double& h) const {
  if (singleLayer) {
    // One surface: the first triangle containing the point is the answer, if on the right side.
    for (std::uint32_t t : items) {
      const Tri& r = tris_[t];
      if (!contains(r, t, u, v)) continue;
      h = heightOf(r, u, v);
      return (Below ? h <= z : h >= z) ? t : kNoTriangle;
    }
    return kNoTriangle;
  }
  std::uint32_t found = kNoTriangle;
  double best = Below ? -std::numeric_limits<double>::infinity() : std::numeric_limits<double>::infinity();
  for (std::uint32_t t : items) {
    const Tri& r = tris_[t];
    const double m = smallestEdge(r, u, v);
    // Inside when the smallest edge value is positive; only within rounding of an edge (|m| at
    // most the error bound, which is rare and so well predicted) is the exact test needed.
    bool in = m > 0;
    if (std::fabs(m) <= r.tol) [[unlikely]] {
      in = inside(t, u, v);
    }
    const double ht = heightOf(r, u, v);
    const bool side = Below ? ht <= z : ht >= z;
    bool better = Below ? ht > best : ht < best;
    if (ht == best) [[unlikely]] {
      better = found != kNoTriangle && cold_[t].polygon < cold_[found].polygon;
    }
    // Bitwise, not short-circuit: a select, not three data-dependent branches.
    const bool take = in & side & better;
    found = take ? t : found;
    best = take ? ht : best;
  }
  h = best;
  return found;
}

}  // namespace qota
