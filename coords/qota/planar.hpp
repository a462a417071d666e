// Planar mappings: every line parallel to one down direction (the Cartesian mapping with any
// gravity, a local east-north-up frame). Each is an affine frame,
//
//     (u, v, h) = R (p - origin),    R a rotation, its last row "up" (against down),
//
// and that frame is all the planar index (lib/core/qota/terrain.hpp) asks of its mapping
// (`frame()`): it is written once over it and never asks which mapping it holds.
#pragma once

#include <Eigen/Core>
#include <concepts>

#include "qota/mapping.hpp"

namespace qota {

struct PlanarFrame {
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();  // world -> mapped
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();        // the world point mapped to (0, 0, 0)
  // rotation is exactly the identity: mapping is an exact subtraction, so raster coordinates
  // round-trip bit for bit.
  bool identity = true;

  Eigen::Vector3d toMapped(const Eigen::Vector3d& world) const {
    if (identity) return world - origin;
    return rotation * (world - origin);
  }
  Eigen::Vector3d toWorld(const Eigen::Vector3d& mapped) const {
    if (identity) return mapped + origin;
    return rotation.transpose() * mapped + origin;
  }
  Eigen::Vector3d directionToMapped(const Eigen::Vector3d& world) const {
    if (identity) return world;
    return rotation * world;
  }
  Eigen::Vector3d directionToWorld(const Eigen::Vector3d& mapped) const {
    if (identity) return mapped;
    return rotation.transpose() * mapped;
  }
};

template <class M>
concept PlanarMapping = CoordinateMapping<M> && requires(const M& m) {
  { m.frame() } -> std::convertible_to<PlanarFrame>;
};

}  // namespace qota
