#include "qota/spherical.hpp"

#include <GeographicLib/Math.hpp>
#include <cmath>

#include "describe.hpp"
#include "qota/error.hpp"

namespace qota {

double longitudeOf(double x, double y) {
  if (x == 0.0 && y == 0.0) return 0.0;  // on the axis: every longitude; pick 0
  const double lon = GeographicLib::Math::atan2d(y, x);
  return lon >= 180.0 ? lon - 360.0 : lon;
}

SphericalMapping::SphericalMapping(const Eigen::Vector3d& centre) : centre_(centre) {
  if (!centre.allFinite()) {
    throw Error("spherical mapping: centre must be finite, got (" + detail::formatVector(centre) + ")");
  }
}

Eigen::Vector3d SphericalMapping::up(double u, double v) {
  double su, cu, sv, cv;
  GeographicLib::Math::sincosd(u, su, cu);
  GeographicLib::Math::sincosd(v, sv, cv);
  return {cv * cu, cv * su, sv};
}

Eigen::Vector3d SphericalMapping::toMapped(const Eigen::Vector3d& world) const {
  const Eigen::Vector3d p = world - centre_;
  const double rho = std::hypot(p.x(), p.y());
  const double r = std::hypot(rho, p.z());
  if (!(r > 0.0) || !std::isfinite(r)) {
    throw Error("spherical mapping: point (" + detail::formatVector(world) +
                ") is at the centre or not finite; it has no longitude or latitude");
  }
  // atan2 of the axial and horizontal parts is accurate at every latitude (asin is not near the
  // poles).
  return {longitudeOf(p.x(), p.y()), GeographicLib::Math::atan2d(p.z(), rho), r};
}

SphericalMapping SphericalMapping::fromParameters(MappingParameters& p) {
  return SphericalMapping(p.vector("centre", Eigen::Vector3d::Zero()));
}

std::string SphericalMapping::describe() const {
  return std::string(name()) + " centre=" + detail::formatVector(centre_);
}

}  // namespace qota
