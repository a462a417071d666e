// Where a line crosses a triangle: the one rule behind alongLine in the planar and the curved
// indexes.
#pragma once

#include <Eigen/Geometry>
#include <cmath>
#include <limits>

#include "qota/predicates.hpp"

namespace qota::detail {

struct LineCrossing {
  double t = 0;            // the line's parameter at the crossing
  Eigen::Vector3d normal;  // the triangle's plane normal (not unit, either side)
};

// The crossing of the line O + t d with the triangle whose corners are O + q[k]. The offsets
// q[k] are rounded once from the corners, the same for every triangle that shares a corner, so
// the exact side of the line against each edge (the sign of det[q[k]; q[k+1]; d]) agrees between
// neighbours on a shared edge and the line cannot slip between them; t and the normal are then
// solved in floating point. False when the line misses the triangle, lies in its plane, or t is
// not a number.
inline bool crossesTriangle(const double q[3][3], const Eigen::Vector3d& d, LineCrossing& out) {
  const double dv[3] = {d.x(), d.y(), d.z()};
  const int s0 = orient3dSign(q[0], q[1], dv), s1 = orient3dSign(q[1], q[2], dv), s2 = orient3dSign(q[2], q[0], dv);
  const bool neg = s0 < 0 || s1 < 0 || s2<0, pos = s0> 0 || s1 > 0 || s2 > 0;
  if (neg == pos) return false;  // outside, or the line lies in the triangle's plane
  const Eigen::Vector3d a(q[0][0], q[0][1], q[0][2]), b(q[1][0], q[1][1], q[1][2]), e(q[2][0], q[2][1], q[2][2]);
  out.normal = (b - a).cross(e - a);
  const double nd = out.normal.dot(d);
  if (nd == 0) return false;
  out.t = out.normal.dot(a) / nd;
  return std::isfinite(out.t);
}

// Whether the open segment O + t d, 0 < t < 1, meets the triangle whose corners are O + q[k]:
// crossesTriangle's rule, t in floating point. Most triangles near a segment lie clearly to one
// side of it seen from above: the vertical plane through it (the sign of d x q in the plane,
// rounded, with a bound on its error) parts them from it before the three exact side tests.
// The one rule of the planar index's segments (PlanarCore::segmentMeets) and of what tries a
// triangle before it (viewshed.cpp).
inline bool segmentMeetsTriangle(const double q[3][3], const Eigen::Vector3d& d) {
  int left = 0, right = 0;
  for (int k = 0; k < 3; ++k) {
    const double a = d.x() * q[k][1], b = d.y() * q[k][0], side = a - b;
    const double bound = 4 * std::numeric_limits<double>::epsilon() * (std::fabs(a) + std::fabs(b));
    left += side > bound, right += side < -bound;
  }
  if (left == 3 || right == 3) return false;
  LineCrossing x;
  return crossesTriangle(q, d, x) && x.t > 0 && x.t < 1;
}

}  // namespace qota::detail
