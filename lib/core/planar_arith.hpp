// The planar index's shared plane arithmetic (private to lib/core): the plane of a triangle from
// its mapped corners, written once for the triangle records, the lean grid's answers, the SIMD
// batch and the shadow test, so that all of them give the same bits.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <string>

namespace qota::planar {

inline constexpr double kUnitRoundoff = 0x1p-53;

// The plane of a triangle from its mapped corners: slopes a = dh/du and b = dh/dv, and the
// height h0 it takes at corner 0. One body for the triangle records and the lean grid, so that
// both give the same bits. (The records also keep the corners' height range, rounded outward to
// floats, to clamp the plane with.)
struct PlaneFit {
  double a, b, h0;
};

// The slopes alone, and the normal's h component: cornerPlane without its sliver check.
struct RawSlopes {
  double a, b, nh;
};

[[gnu::always_inline]] inline RawSlopes rawSlopes(double u0, double v0, double h0, double u1, double v1, double h1,
                                                  double u2, double v2, double h2) {
  const double d1u = u1 - u0, d1v = v1 - v0, d1h = h1 - h0;
  const double d2u = u2 - u0, d2v = v2 - v0, d2h = h2 - h0;
  const double nu = d1v * d2h - d1h * d2v, nv = d1h * d2u - d1u * d2h, nh = d1u * d2v - d1v * d2u;
  // One division for both slopes, not two; -x * q is x * -q.
  const double q = -1.0 / nh;
  return {nu * q, nv * q, nh};
}

[[gnu::always_inline]] inline PlaneFit cornerPlane(double u0, double v0, double h0, double u1, double v1, double h1,
                                                   double u2, double v2, double h2) {
  const RawSlopes r = rawSlopes(u0, v0, h0, u1, v1, h1, u2, v2, h2);
  PlaneFit p{r.a, r.b, h0};
  if (!(r.nh > 0) || !std::isfinite(p.a) || !std::isfinite(p.b)) [[unlikely]] {
    // A sliver with nonzero exact area whose plane is vertical to within rounding. It stays in
    // the index, or its neighbours would open a crack; its height is its corners' mid-range.
    p.a = p.b = 0;
    p.h0 = 0.5 * (std::min(h0, std::min(h1, h2)) + std::max(h0, std::max(h1, h2)));
  }
  return p;
}

inline PlaneFit cornerPlane(const double u[3], const double v[3], const double h[3]) {
  return cornerPlane(u[0], v[0], h[0], u[1], v[1], h[1], u[2], v[2], h[2]);
}

// A point as "(x, y, z)", for error messages.
inline std::string describePoint(const Eigen::Vector3d& p) {
  return "(" + std::to_string(p.x()) + ", " + std::to_string(p.y()) + ", " + std::to_string(p.z()) + ")";
}

}  // namespace qota::planar
