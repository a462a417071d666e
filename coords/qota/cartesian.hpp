// Cartesian mapping: a flat world with one constant gravity direction.
//
// World frame: right-handed x, y, z in any linear unit (metres, or a raster CRS's units).
// Mapped coordinates: u, v horizontal and h "up", i.e. against gravity, in the same units:
//
//     (u, v, h) = R * (p - origin)
//
// where R is the rotation that takes the gravity direction to -Z (the paper's "rotate the world
// until the preferred direction is -Z"). R is the smallest rotation doing so (about the axis
// gravity x -Z), so a gravity close to -Z keeps u and v close to x and y. When gravity is exactly
// along -Z, R is the identity and the mapping is an exact subtraction, so raster coordinates
// round-trip bit for bit.
//
// The line for (u, v) is p(t) = toWorld(u, v, 0) + t * down, with down the unit gravity vector;
// every (u, v) is in the domain (the plane is unbounded, no axis is periodic). See
// coords/README.md for the catalogue of all coordinate spaces.
#pragma once

#include <Eigen/Core>
#include <limits>
#include <string>

#include "qota/mapping.hpp"
#include "qota/planar.hpp"

namespace qota {

class CartesianMapping {
 public:
  // gravity: any nonzero finite vector (its length is ignored). origin: the world point that maps
  // to (0, 0, 0); put it near the data when world coordinates are large (map coordinates in the
  // millions) so that mapped coordinates keep their precision. Throws qota::Error otherwise.
  explicit CartesianMapping(const Eigen::Vector3d& gravity = Eigen::Vector3d(0, 0, -1),
                            const Eigen::Vector3d& origin = Eigen::Vector3d::Zero());

  static constexpr const char* name() { return "cartesian"; }
  static constexpr bool kHeightUp = true;

  Eigen::Vector3d toMapped(const Eigen::Vector3d& world) const { return frame_.toMapped(world); }
  Eigen::Vector3d toWorld(const Eigen::Vector3d& mapped) const { return frame_.toWorld(mapped); }
  // A direction (e.g. a surface normal) from mapped coordinates to the world frame.
  Eigen::Vector3d directionToWorld(const Eigen::Vector3d& mapped) const { return frame_.directionToWorld(mapped); }
  MappedLine line(double u, double v) const { return {toWorld({u, v, 0.0}), gravity_}; }
  MappedDomain domain() const {
    constexpr double inf = std::numeric_limits<double>::infinity();
    return {-inf, inf, -inf, inf, false};
  }

  const Eigen::Vector3d& gravity() const { return gravity_; }  // unit
  const Eigen::Vector3d& origin() const { return frame_.origin; }
  const Eigen::Matrix3d& rotation() const { return frame_.rotation; }  // world -> mapped
  // True when gravity is exactly -Z and the mapping is a pure translation.
  bool vertical() const { return frame_.identity; }
  // As a planar mapping (planar.hpp).
  const PlanarFrame& frame() const { return frame_; }

  // "cartesian gravity=gx,gy,gz origin=ox,oy,oz", with round-trip precision (the gravity as
  // given, so that parsing it back builds the identical mapping).
  std::string describe() const;
  static CartesianMapping fromParameters(MappingParameters& p);  // gravity=, origin=

 private:
  Eigen::Vector3d given_;  // the gravity as given, for describe(): an exact round trip
  Eigen::Vector3d gravity_;
  PlanarFrame frame_;  // R (the rotation taking gravity to -Z) and the origin
};

}  // namespace qota
