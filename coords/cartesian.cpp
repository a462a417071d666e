#include "qota/cartesian.hpp"

#include <Eigen/Geometry>
#include <cmath>

#include "describe.hpp"
#include "qota/error.hpp"

namespace qota {

using detail::formatVector;

CartesianMapping::CartesianMapping(const Eigen::Vector3d& gravity, const Eigen::Vector3d& origin) : given_(gravity) {
  if (!gravity.allFinite() || gravity.squaredNorm() == 0.0) {
    throw Error("cartesian mapping: gravity must be a nonzero finite vector, got (" + formatVector(gravity) + ")");
  }
  if (!origin.allFinite()) {
    throw Error("cartesian mapping: origin must be finite, got (" + formatVector(origin) + ")");
  }
  frame_.origin = origin;
  frame_.identity = gravity.x() == 0.0 && gravity.y() == 0.0 && gravity.z() < 0.0;
  if (frame_.identity) {
    gravity_ = Eigen::Vector3d(0, 0, -1);
    frame_.rotation.setIdentity();
  } else {
    gravity_ = gravity.normalized();
    // The minimal rotation taking gravity onto -Z; Eigen handles the antiparallel case (gravity
    // along +Z) by picking a rotation axis perpendicular to it.
    frame_.rotation =
        Eigen::Quaterniond::FromTwoVectors(gravity_, Eigen::Vector3d(0, 0, -1)).normalized().toRotationMatrix();
  }
}

CartesianMapping CartesianMapping::fromParameters(MappingParameters& p) {
  const Eigen::Vector3d gravity = p.vector("gravity", {0, 0, -1});
  return CartesianMapping(gravity, p.vector("origin", Eigen::Vector3d::Zero()));
}

std::string CartesianMapping::describe() const {
  return std::string(name()) + " gravity=" + formatVector(given_) + " origin=" + formatVector(frame_.origin);
}

}  // namespace qota
