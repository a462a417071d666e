// East-north-up mapping: a local tangent plane of an ellipsoid, for Earth-centred (ECEF) data
// over an area small enough to be flat (a city, an airfield, a vehicle's surroundings).
//
// World frame: ECEF x, y, z in metres on the ellipsoid (a, f), as GeographicLib::Geocentric.
// Mapped coordinates: u east, v north, h up, in metres, from the origin point (lat0, lon0, h0):
//
//     (u, v, h) = R (p - origin),   R's rows the unit east, north and up at (lat0, lon0)
//
// the same as GeographicLib::LocalCartesian. Every line is parallel to -up at the origin
// (gravity of the tangent plane, not the ellipsoid's normal under each point: over 10 km the
// two differ by 0.09 degrees); for whole continents or planets use the geodetic mapping. A
// planar mapping (planar.hpp): the planar index serves it as it serves the Cartesian one.
#pragma once

#include <Eigen/Core>
#include <limits>
#include <string>

#include "qota/mapping.hpp"
#include "qota/planar.hpp"

namespace qota {

class EnuMapping {
 public:
  // lat0 in [-90, 90] and lon0 finite, in degrees; h0 finite, metres above the ellipsoid; a > 0
  // and 0 <= f < 1 (default WGS84). Throws qota::Error naming the bad value otherwise.
  EnuMapping(double lat0, double lon0, double h0 = 0.0);
  EnuMapping(double lat0, double lon0, double h0, double a, double f);

  static constexpr const char* name() { return "enu"; }
  static constexpr bool kHeightUp = true;

  Eigen::Vector3d toMapped(const Eigen::Vector3d& world) const { return frame_.toMapped(world); }
  Eigen::Vector3d toWorld(const Eigen::Vector3d& mapped) const { return frame_.toWorld(mapped); }
  MappedLine line(double u, double v) const { return {toWorld({u, v, 0.0}), -up()}; }
  MappedDomain domain() const {
    constexpr double inf = std::numeric_limits<double>::infinity();
    return {-inf, inf, -inf, inf, false};
  }
  const PlanarFrame& frame() const { return frame_; }

  double latitude() const { return lat0_; }
  double longitude() const { return lon0_; }
  double height() const { return h0_; }
  double a() const { return a_; }
  double f() const { return f_; }
  const Eigen::Vector3d& origin() const { return frame_.origin; }  // ECEF of (lat0, lon0, h0)
  Eigen::Vector3d east() const { return frame_.rotation.row(0).transpose(); }
  Eigen::Vector3d north() const { return frame_.rotation.row(1).transpose(); }
  Eigen::Vector3d up() const { return frame_.rotation.row(2).transpose(); }

  // "enu lat=.. lon=.. h=.. a=.. f=..", with round-trip precision.
  std::string describe() const;
  static EnuMapping fromParameters(MappingParameters& p);  // lat=, lon=, h=, a=, f=

 private:
  double lat0_, lon0_, h0_, a_, f_;
  PlanarFrame frame_;
};

}  // namespace qota
