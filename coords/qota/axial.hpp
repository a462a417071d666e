// Axial mappings: the curved mappings (spherical, geodetic, cylindrical), whose lines all meet
// one axis. This is what such a mapping tells the curved index (lib/core/qota/curved.hpp), which
// is written once over it and never asks which mapping it holds:
//
//   kPoles                     v is a latitude: at domain().vlo and vhi every u is one line
//   toLocal(world), fromLocal(local), directionToLocal(direction), directionFromLocal(direction)
//                              the local frame: the axis as +z through 0, where lines are simple
//   axialLine(u, v)            the line of (u, v) in the local frame: (0, 0, s) + t d, d unit at
//                              angle u around the axis, its point at t having h = t - hOffset
//   footprintHeight(world)     a vertex's value that footprintV needs (the geodetic height; 0
//                              for a mapping that needs none), computed once per vertex
//   footprintV(p, h, scale)    a conservative v range of every line that can meet the local
//                              triangle p (corners' footprintHeight h; scale bounds the local
//                              coordinates), padded for the rounding of a query's line
//
// u is always the angle of a local point around +z (atan2 of y and x), so the u range of a
// footprint is the index's to compute, the same for every axial mapping.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <concepts>

#include "qota/mapping.hpp"

namespace qota {

struct AxialLine {
  double s;        // the line's point on the axis: (0, 0, s)
  double d[3];     // unit direction, toward increasing t
  double hOffset;  // the mapping's h of the point at t is t - hOffset
};

template <class M>
concept AxialMapping = CoordinateMapping<M> &&
    requires(const M& m, const Eigen::Vector3d& p, const Eigen::Vector3d (&tri)[3], const double (&h)[3], double u,
             double v, double& lo, double& hi) {
  { M::kPoles } -> std::convertible_to<bool>;
  { m.toLocal(p) } -> std::same_as<Eigen::Vector3d>;
  { m.fromLocal(p) } -> std::same_as<Eigen::Vector3d>;
  { m.directionToLocal(p) } -> std::same_as<Eigen::Vector3d>;
  { m.directionFromLocal(p) } -> std::same_as<Eigen::Vector3d>;
  { m.axialLine(u, v) } -> std::same_as<AxialLine>;
  { m.footprintHeight(p) } -> std::same_as<double>;
  {m.footprintV(tri, h, u, lo, hi)};
};

namespace axial {

// Footprint boxes are widened by this many degrees: far more than the rounding of an angle from
// atan2 or of a query direction from sinCosDegrees (a few 1e-14 degrees), far less than any
// polygon.
constexpr double kPadDegrees = 1e-9;

// sin and cos of an angle in degrees for a query line, inline: reduced exactly to the nearest
// multiple of 90 degrees (so the axes and the poles come out exact, as with GeographicLib's
// sincosd), then Taylor series on |r| <= pi/4, whose truncation error is below 2e-17. About five
// times faster than two libm calls, which matters at a hundred nanoseconds a query.
inline void sinCosDegrees(double x, double& s, double& c) {
  const double q = std::nearbyint(x * (1.0 / 90.0));
  const double r = (x - 90.0 * q) * (M_PI / 180.0);  // x - 90 q is exact for |x| < 2^44
  const double r2 = r * r;
  const double sr =
      r * (1 + r2 * (-1.0 / 6 +
                     r2 * (1.0 / 120 +
                           r2 * (-1.0 / 5040 +
                                 r2 * (1.0 / 362880 + r2 * (-1.0 / 39916800 +
                                                            r2 * (1.0 / 6227020800 + r2 * (-1.0 / 1307674368000))))))));
  const double cr =
      1 + r2 * (-0.5 +
                r2 * (1.0 / 24 +
                      r2 * (-1.0 / 720 +
                            r2 * (1.0 / 40320 + r2 * (-1.0 / 3628800 +
                                                      r2 * (1.0 / 479001600 + r2 * (-1.0 / 87178291200 +
                                                                                    r2 * (1.0 / 20922789888000))))))));
  switch (static_cast<long long>(q) & 3) {
    case 0:
      s = sr, c = cr;
      break;
    case 1:
      s = cr, c = -sr;
      break;
    case 2:
      s = -sr, c = -cr;
      break;
    default:
      s = -cr, c = sr;
      break;
  }
  if (s == 0.0) s = 0.0;  // no negative zeros
  if (c == 0.0) c = 0.0;
}

// Latitude range (degrees) of the central projection of triangle p seen from 0: its vertices plus
// the interior extremum of each great-circle arc.
void latitudeRange(const Eigen::Vector3d (&p)[3], double& lo, double& hi);

// Pads a latitude range by kPadDegrees, within [-90, 90].
inline void padLatitudes(double& lo, double& hi) {
  lo = std::max(-90.0, lo - kPadDegrees);
  hi = std::min(90.0, hi + kPadDegrees);
}

}  // namespace axial
}  // namespace qota
