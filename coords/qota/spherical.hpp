// Spherical mapping: radial gravity around a centre (planets, moons, asteroids).
//
// u = longitude theta in degrees, [-180, 180), east positive, 0 on the world +x axis, 90 on +y;
// v = latitude phi in degrees, [-90, 90], positive toward world +z;
// h = radius r, the distance from the centre, in world units.
// Right-handed: (east, north, up) at every point off the poles. Down points to the centre, so the
// line of (u, v) is the ray centre + r * up(u, v), r >= 0, and "below" means a smaller radius.
//
// Poles: at v = +-90 every u names the same ray (toMapped returns u = 0 there). Seam: u = -180
// and u = 180 are the same meridian; toMapped returns -180. The centre itself has no direction:
// toMapped throws there. Trigonometry is in degrees with exact quadrant reduction
// (GeographicLib's Math::sincosd), so the poles, the equator and the seam map exactly.
#pragma once

#include <Eigen/Core>
#include <string>

#include "qota/axial.hpp"
#include "qota/mapping.hpp"

namespace qota {

class SphericalMapping {
 public:
  // centre: finite (throws qota::Error otherwise).
  explicit SphericalMapping(const Eigen::Vector3d& centre = Eigen::Vector3d::Zero());

  static constexpr const char* name() { return "spherical"; }
  static constexpr bool kHeightUp = true;

  Eigen::Vector3d toMapped(const Eigen::Vector3d& world) const;
  Eigen::Vector3d toWorld(const Eigen::Vector3d& mapped) const {
    return centre_ + mapped.z() * up(mapped.x(), mapped.y());
  }
  // Unit radial direction of (u, v) (degrees).
  static Eigen::Vector3d up(double u, double v);
  MappedLine line(double u, double v) const { return {centre_, -up(u, v)}; }
  MappedDomain domain() const { return {-180.0, 180.0, -90.0, 90.0, true}; }
  std::string describe() const;  // "spherical centre=x,y,z"
  static SphericalMapping fromParameters(MappingParameters& p);

  // As an axial mapping (axial.hpp): the local frame is centred, the lines pass through the centre.
  static constexpr bool kPoles = true;
  Eigen::Vector3d toLocal(const Eigen::Vector3d& world) const { return world - centre_; }
  Eigen::Vector3d fromLocal(const Eigen::Vector3d& local) const { return local + centre_; }
  static Eigen::Vector3d directionToLocal(const Eigen::Vector3d& d) { return d; }
  static Eigen::Vector3d directionFromLocal(const Eigen::Vector3d& d) { return d; }
  static AxialLine axialLine(double u, double v) {
    double su, cu, sv, cv;
    axial::sinCosDegrees(u, su, cu);
    axial::sinCosDegrees(v, sv, cv);
    return {0.0, {cv * cu, cv * su, sv}, 0.0};
  }
  static double footprintHeight(const Eigen::Vector3d&) { return 0.0; }
  // Great-circle arcs: the latitudes the triangle's central projection reaches.
  static void footprintV(const Eigen::Vector3d (&p)[3], const double (&)[3], double, double& lo, double& hi) {
    axial::latitudeRange(p, lo, hi);
    axial::padLatitudes(lo, hi);
  }

  const Eigen::Vector3d& centre() const { return centre_; }

 private:
  Eigen::Vector3d centre_;
};

// Longitude and latitude (degrees) of a direction, with the conventions above: lon in
// [-180, 180), lon = 0 when the direction is along +-z. Shared by the spherical and geodetic
// mappings (longitude is the same on a sphere and an ellipsoid of revolution).
double longitudeOf(double x, double y);

}  // namespace qota
