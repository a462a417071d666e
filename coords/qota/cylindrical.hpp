// Cylindrical mapping: a rotating space station, whose centrifugal gravity points away from the
// spin axis.
//
// The axis is a point c and a unit direction k. A rotation R takes k to the local +z axis (the
// identity when k is +z, so a station built along z maps exactly); the local x axis is angle 0.
// u = angle around the axis in degrees, [-180, 180), counter-clockwise seen from +k (right-handed
//     about k), 0 on R^T x;
// v = signed distance along the axis from c, world units;
// h = distance from the axis, world units, >= 0.
// Down points away from the axis (outward), so h grows *along* down (kHeightUp is false): the
// floor of a station is at large h, and "below" a point means a larger h. The line of (u, v) is
// the ray c + v k + h * out(u), h >= 0.
//
// Seam: u = -180 and 180 are the same half-plane; toMapped returns -180. A point on the axis (to
// within the rounding of the frame change, 1e-14 of its distance from the axis point) has no
// angle: toMapped throws there. The domain is unbounded along v.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "qota/axial.hpp"
#include "qota/mapping.hpp"

namespace qota {

class CylindricalMapping {
 public:
  // axisPoint finite, axisDirection nonzero and finite (normalized here); throws qota::Error.
  explicit CylindricalMapping(const Eigen::Vector3d& axisPoint = Eigen::Vector3d::Zero(),
                              const Eigen::Vector3d& axisDirection = Eigen::Vector3d(0, 0, 1));

  static constexpr const char* name() { return "cylindrical"; }
  static constexpr bool kHeightUp = false;

  Eigen::Vector3d toMapped(const Eigen::Vector3d& world) const;
  Eigen::Vector3d toWorld(const Eigen::Vector3d& mapped) const;
  // World unit vector pointing away from the axis at angle u (degrees): the down direction.
  Eigen::Vector3d out(double u) const;
  MappedLine line(double u, double v) const { return {point_ + v * axis_, out(u)}; }
  MappedDomain domain() const {
    constexpr double inf = std::numeric_limits<double>::infinity();
    return {-180.0, 180.0, -inf, inf, true};
  }
  std::string describe() const;  // "cylindrical point=x,y,z axis=x,y,z"
  static CylindricalMapping fromParameters(MappingParameters& p);

  const Eigen::Vector3d& axisPoint() const { return point_; }
  const Eigen::Vector3d& axisDirection() const { return axis_; }  // unit
  const Eigen::Matrix3d& rotation() const { return rotation_; }   // world -> local (k = +z)
  // Local frame: x, y across the axis, z along it, origin at the axis point.
  Eigen::Vector3d toLocal(const Eigen::Vector3d& world) const;
  Eigen::Vector3d fromLocal(const Eigen::Vector3d& local) const;

  // As an axial mapping (axial.hpp): the line of (u, v) leaves the axis at s = v, outward.
  static constexpr bool kPoles = false;
  Eigen::Vector3d directionToLocal(const Eigen::Vector3d& d) const {
    return alongZ_ ? d : Eigen::Vector3d(rotation_ * d);
  }
  Eigen::Vector3d directionFromLocal(const Eigen::Vector3d& d) const {
    return alongZ_ ? d : Eigen::Vector3d(rotation_.transpose() * d);
  }
  static AxialLine axialLine(double u, double v) {
    double su, cu;
    axial::sinCosDegrees(u, su, cu);
    return {v, {cu, su, 0.0}, 0.0};
  }
  static double footprintHeight(const Eigen::Vector3d&) { return 0.0; }
  // v is the axial coordinate: the corners' range, padded relative to the coordinates' scale.
  static void footprintV(const Eigen::Vector3d (&p)[3], const double (&)[3], double scale, double& lo, double& hi) {
    lo = std::min({p[0].z(), p[1].z(), p[2].z()});
    hi = std::max({p[0].z(), p[1].z(), p[2].z()});
    const double pad = 1e-12 * (std::fabs(lo) + std::fabs(hi) + scale);
    lo -= pad, hi += pad;
  }

 private:
  Eigen::Vector3d point_;
  Eigen::Vector3d given_;  // the axis direction as given, for describe()
  Eigen::Vector3d axis_;
  Eigen::Matrix3d rotation_;
  bool alongZ_;
};

}  // namespace qota
