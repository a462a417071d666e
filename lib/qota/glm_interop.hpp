// GLM interop: hand qota's results to rendering code that speaks glm.
//
// qota computes in double precision with Eigen types; renderers usually hold glm vectors and
// 4x4 matrices. These helpers convert, and build the model matrix of an object standing on the
// terrain: its origin at the hit point, its local +Z along the surface normal, and its heading
// (local +X) kept as close as possible to a requested direction.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <glm/glm.hpp>

#include "qota/terrain.hpp"

namespace qota {

inline glm::dvec3 toGlm(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }
inline Eigen::Vector3d fromGlm(const glm::dvec3& v) { return {v.x, v.y, v.z}; }

// A rigid pose: position and orientation (columns: the object's x, y, z axes in the world).
struct Pose {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Matrix3d orientation = Eigen::Matrix3d::Identity();
};

// The column-major model matrix of a pose (glm's convention: m[column][row]).
inline glm::dmat4 toGlm(const Pose& pose) {
  glm::dmat4 m(1.0);
  for (int c = 0; c < 3; ++c) {
    for (int r = 0; r < 3; ++r) m[c][r] = pose.orientation(r, c);
    m[3][c] = pose.position[c];
  }
  return m;
}

// The pose of an object resting on a hit: up along the normal, heading as near `forward` (a
// world direction) as the surface allows. When forward is parallel to the normal, any
// perpendicular heading is used.
inline Pose poseOnHit(const Hit& hit, const Eigen::Vector3d& forward) {
  const Eigen::Vector3d z = hit.normal.normalized();
  Eigen::Vector3d x = forward - forward.dot(z) * z;
  if (x.squaredNorm() < 1e-24) x = z.unitOrthogonal();
  x.normalize();
  Pose pose;
  pose.position = hit.world;
  pose.orientation.col(0) = x;
  pose.orientation.col(1) = z.cross(x);
  pose.orientation.col(2) = z;
  return pose;
}

inline glm::dvec3 glmPosition(const Hit& hit) { return toGlm(hit.world); }
inline glm::dvec3 glmNormal(const Hit& hit) { return toGlm(hit.normal); }

}  // namespace qota
