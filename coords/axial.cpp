#include "qota/axial.hpp"

#include <Eigen/Geometry>
#include <GeographicLib/Math.hpp>
#include <algorithm>
#include <limits>

namespace qota::axial {
namespace {

double latitudeOf(const Eigen::Vector3d& p) { return GeographicLib::Math::atan2d(p.z(), std::hypot(p.x(), p.y())); }

}  // namespace

void latitudeRange(const Eigen::Vector3d (&p)[3], double& lo, double& hi) {
  lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (int i = 0; i < 3; ++i) {
    const Eigen::Vector3d& a = p[i];
    const Eigen::Vector3d& b = p[(i + 1) % 3];
    lo = std::min(lo, latitudeOf(a)), hi = std::max(hi, latitudeOf(a));
    const Eigen::Vector3d n = a.cross(b);
    if (n.squaredNorm() == 0.0) continue;
    // The highest point of the great circle with normal n, and the lowest (its opposite).
    const Eigen::Vector3d top(-n.x() * n.z(), -n.y() * n.z(), n.x() * n.x() + n.y() * n.y());
    for (const Eigen::Vector3d& q : {top, Eigen::Vector3d(-top)}) {
      if (a.cross(q).dot(n) > 0.0 && q.cross(b).dot(n) > 0.0) {
        const double lat = latitudeOf(q);
        lo = std::min(lo, lat), hi = std::max(hi, lat);
      }
    }
  }
}

}  // namespace qota::axial
