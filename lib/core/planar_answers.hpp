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
  for (std::uint32_t t : items) __builtin_prefetch(&tris_[t]);
}

// The error bound of the edge values below, relative to s (s + |du| + |dv|), s the sum of the
// offsets' magnitudes. The stored offsets f are the true ones within 2^-24 |f| each (one rounding
// to float after an exact or once-rounded difference in double): an edge value of the float
// triangle differs from the true one by at most about 2^-24 s (|du| + |dv|) (edges 0 and 2, at
// corner 0) or 2^-23 s (s + |du| + |dv|) (edge 1, through the area), and the arithmetic in double
// adds a few 2^-53 of the same. 2^-21 leaves a margin of four. The floor covers products that
// underflow (a point within 1e-300 of corner 0). Offsets a normal float cannot hold are stored as
// NaN (edgeRecord): every comparison is then false and the exact test decides.
inline constexpr double kEdgeRelative = 0x1p-21, kEdgeFloor = 0x1p-1000;

[[gnu::always_inline]] inline double PlanarCore::offsetSum(const Tri& r) {
  return (std::fabs(double{r.du1}) + std::fabs(double{r.dv1})) + (std::fabs(double{r.du2}) + std::fabs(double{r.dv2}));
}

[[gnu::always_inline]] inline double PlanarCore::edgeBound(double s, double du, double dv) {
  return kEdgeRelative * s * (s + std::fabs(du) + std::fabs(dv)) + kEdgeFloor;
}

// Edge k of the float triangle (corner 0, 0 + f1, 0 + f2, counter-clockwise) at the point d from
// corner 0: e0 = f1 x d, e2 = d x f2, and e1 from the barycentric identity e0 + e1 + e2 = f1 x f2
// (the products of floats are exact in double).
[[gnu::always_inline]] inline PlanarCore::EdgeValues PlanarCore::edgeValues(const Tri& r, double u, double v) {
  const double du = u - r.u0, dv = v - r.v0;
  const double u1 = r.du1, v1 = r.dv1, u2 = r.du2, v2 = r.dv2;
  const double e0 = u1 * dv - v1 * du;
  const double e2 = v2 * du - u2 * dv;
  const double e1 = (u1 * v2 - v1 * u2) - e0 - e2;
  return {{e0, e1, e2}, edgeBound(offsetSum(r), du, dv)};
}

[[gnu::always_inline]] inline PlanarCore::EdgeTest PlanarCore::edgeTest(const Tri& r, double u, double v) {
  const EdgeValues x = edgeValues(r, u, v);
  // e1 first: it is NaN whenever e0 or e2 is (std::min keeps its first argument's NaN).
  return {std::min(x.e[1], std::min(x.e[0], x.e[2])), x.tol};
}

// Each edge at the box corner farthest inside it (by the signs of its gradient), with the bound
// there: the box is certainly outside when that value is below minus the bound. (NaN offsets
// compare false: the triangle stays; so does a value that overflowed, with domains beyond 1e270.)
inline bool PlanarCore::edgesReach(const Tri& r, const Box2& b) {
  const double u1 = r.du1, v1 = r.dv1, u2 = r.du2, v2 = r.dv2;
  const double s = offsetSum(r);
  // Edge 0 (gradient (-v1, u1)), edge 2 ((v2, -u2)), then edge 1 ((v1 - v2, u2 - u1)).
  double du = (v1 <= 0 ? b.uhi : b.ulo) - r.u0, dv = (u1 >= 0 ? b.vhi : b.vlo) - r.v0;
  const auto outside = [&](double value) { return value < -edgeBound(s, du, dv) && std::isfinite(value); };
  if (outside(u1 * dv - v1 * du)) return false;
  du = (v2 >= 0 ? b.uhi : b.ulo) - r.u0, dv = (u2 <= 0 ? b.vhi : b.vlo) - r.v0;
  if (outside(v2 * du - u2 * dv)) return false;
  du = (v1 >= v2 ? b.uhi : b.ulo) - r.u0, dv = (u2 >= u1 ? b.vhi : b.vlo) - r.v0;
  return !outside((u1 * v2 - v1 * u2) - (u1 * dv - v1 * du) - (v2 * du - u2 * dv));
}

inline bool PlanarCore::contains(const Tri& r, std::uint32_t t, double u, double v) const {
  const EdgeTest e = edgeTest(r, u, v);
  if (e.undecided()) [[unlikely]]
    return inside(t, u, v);
  return e.m > 0;
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
    const EdgeTest e = edgeTest(r, u, v);
    // Inside when the smallest edge value is positive; only within rounding of an edge (|m| at
    // most the error bound, which is rare and so well predicted) is the exact test needed.
    bool in = e.m > 0;
    if (e.undecided()) [[unlikely]] {
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
