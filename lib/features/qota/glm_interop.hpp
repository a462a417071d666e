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

#include "qota/follow.hpp"  // Pose, poseOnHit

namespace qota {

inline glm::dvec3 toGlm(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }
inline Eigen::Vector3d fromGlm(const glm::dvec3& v) { return {v.x, v.y, v.z}; }

// The column-major model matrix of a pose (glm's convention: m[column][row]).
inline glm::dmat4 toGlm(const Pose& pose) {
  glm::dmat4 m(1.0);
  for (int c = 0; c < 3; ++c) {
    for (int r = 0; r < 3; ++r) m[c][r] = pose.orientation(r, c);
    m[3][c] = pose.position[c];
  }
  return m;
}

inline glm::dvec3 glmPosition(const Hit& hit) { return toGlm(hit.world); }
inline glm::dvec3 glmNormal(const Hit& hit) { return toGlm(hit.normal); }

}  // namespace qota
