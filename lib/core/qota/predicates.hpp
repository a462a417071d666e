// Exact 2D orientation, the predicate that makes qota's point-in-polygon test watertight.
//
// orient2d(a, b, c) is twice the signed area of triangle abc: positive when c lies to the left of
// the directed line a->b (counter-clockwise turn), negative to the right, zero when collinear.
// orient2dSign returns the sign of the exact real-number value for the given doubles, never a
// rounded one, so two triangles sharing an edge always agree on which side of it a point lies, and
// a point exactly on the edge is "on" (zero) for both.
//
// The exact path writes the determinant as six products, splits each into a rounded value and its
// exact error with fma, and sums the twelve terms into a non-overlapping floating-point expansion
// (Priest/Shewchuk's expansion arithmetic). The sign of an expansion is the sign of its largest
// component. It is about 100 times slower than the plain determinant, so the hot paths call it
// only when a filtered floating-point evaluation cannot decide (see CartesianIndex).
//
// Valid for all finite inputs whose products neither overflow nor underflow (|coordinate| between
// about 1e-150 and 1e150, or zero), far beyond any terrain.
#pragma once

#include <cmath>

#include "qota/vocabulary.hpp"

namespace qota {

// Sign (-1, 0, +1) of the exact orient2d(a, b, c), by expansion arithmetic.
int orient2dSignExact(Point2 a, Point2 b, Point2 c);

// Sign (-1, 0, +1) of the exact orient2d(a, b, c). Inline, so that the rounded determinant, exact
// in sign when it exceeds its error bound, costs no call; the rest goes to the expansions.
inline int orient2dSign(Point2 a, Point2 b, Point2 c) {
  const double left = (a.u - c.u) * (b.v - c.v);
  const double right = (a.v - c.v) * (b.u - c.u);
  const double det = left - right;
  // 8 units in the last place of the magnitude sum bounds the error of the three roundings of the
  // differences, two products and the subtraction (Shewchuk's bound is (3 + 16u)u).
  const double bound = 8.0 * 1.1102230246251565e-16 * (std::fabs(left) + std::fabs(right));
  if (det > bound) return 1;
  if (det < -bound) return -1;
  return orient2dSignExact(a, b, c);
}

// The plain floating-point determinant, for callers that filter it themselves.
inline double orient2dApprox(Point2 a, Point2 b, Point2 c) {
  return (a.u - c.u) * (b.v - c.v) - (a.v - c.v) * (b.u - c.u);
}

// Whether the closed segments ab and cd share a point, by exact orientations (collinear ones by
// their boxes). Same range of validity as orient2dSign.
bool segmentsMeet(Point2 a, Point2 b, Point2 c, Point2 d);

// Sign (-1, 0, +1) of the exact determinant det[a; b; d] = a . (b x d): which side of the plane
// through the origin, a and b the point d lies on. The curved mappings' line test (curved.hpp)
// calls it when its filtered evaluation cannot decide. Same range of validity as orient2dSign.
int orient3dSign(const double a[3], const double b[3], const double d[3]);

}  // namespace qota
