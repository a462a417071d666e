#include "qota/cylindrical.hpp"

#include <Eigen/Geometry>
#include <GeographicLib/Math.hpp>
#include <cmath>

#include "describe.hpp"
#include "qota/error.hpp"
#include "qota/spherical.hpp"

namespace qota {

CylindricalMapping::CylindricalMapping(const Eigen::Vector3d& axisPoint, const Eigen::Vector3d& axisDirection)
    : point_(axisPoint), given_(axisDirection) {
  if (!axisPoint.allFinite()) {
    throw Error("cylindrical mapping: axis point must be finite, got (" + detail::formatVector(axisPoint) + ")");
  }
  if (!axisDirection.allFinite() || axisDirection.squaredNorm() == 0.0) {
    throw Error("cylindrical mapping: axis direction must be a nonzero finite vector, got (" +
                detail::formatVector(axisDirection) + ")");
  }
  alongZ_ = axisDirection.x() == 0.0 && axisDirection.y() == 0.0 && axisDirection.z() > 0.0;
  if (alongZ_) {
    axis_ = Eigen::Vector3d(0, 0, 1);
    rotation_.setIdentity();
  } else {
    axis_ = axisDirection.normalized();
    rotation_ = Eigen::Quaterniond::FromTwoVectors(axis_, Eigen::Vector3d(0, 0, 1)).normalized().toRotationMatrix();
  }
}

Eigen::Vector3d CylindricalMapping::toLocal(const Eigen::Vector3d& world) const {
  if (alongZ_) return world - point_;
  return rotation_ * (world - point_);
}

Eigen::Vector3d CylindricalMapping::fromLocal(const Eigen::Vector3d& local) const {
  if (alongZ_) return local + point_;
  return rotation_.transpose() * local + point_;
}

Eigen::Vector3d CylindricalMapping::out(double u) const {
  double su, cu;
  GeographicLib::Math::sincosd(u, su, cu);
  const Eigen::Vector3d local(cu, su, 0.0);
  return alongZ_ ? local : Eigen::Vector3d(rotation_.transpose() * local);
}

Eigen::Vector3d CylindricalMapping::toMapped(const Eigen::Vector3d& world) const {
  const Eigen::Vector3d p = toLocal(world);
  const double h = std::hypot(p.x(), p.y());
  if (!(h > 1e-14 * std::fabs(p.z())) || !std::isfinite(h) || !std::isfinite(p.z())) {
    throw Error("cylindrical mapping: point (" + detail::formatVector(world) +
                ") is on the axis or not finite; it has no angle");
  }
  return {longitudeOf(p.x(), p.y()), p.z(), h};
}

Eigen::Vector3d CylindricalMapping::toWorld(const Eigen::Vector3d& mapped) const {
  double su, cu;
  GeographicLib::Math::sincosd(mapped.x(), su, cu);
  return fromLocal({mapped.z() * cu, mapped.z() * su, mapped.y()});
}

CylindricalMapping CylindricalMapping::fromParameters(MappingParameters& p) {
  const Eigen::Vector3d point = p.vector("point", Eigen::Vector3d::Zero());
  return CylindricalMapping(point, p.vector("axis", {0, 0, 1}));
}

std::string CylindricalMapping::describe() const {
  return std::string(name()) + " point=" + detail::formatVector(point_) + " axis=" + detail::formatVector(given_);
}

}  // namespace qota
