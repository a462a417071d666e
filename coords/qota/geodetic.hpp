// Geodetic mapping: an ellipsoid of revolution (the Earth's WGS84 by default) with "down" along
// the ellipsoid normal, through GeographicLib's exact geocentric conversion.
//
// World frame: geocentric (ECEF) x, y, z in metres, centre at the origin, z the polar axis.
// u = geodetic longitude in degrees, [-180, 180), east positive;
// v = geodetic latitude in degrees, [-90, 90] (the angle of the ellipsoid normal to the equator);
// h = height above the ellipsoid along its normal, metres.
// Right-handed (east, north, up). The line of (u, v) is the ellipsoid normal through the surface
// point of (u, v): a straight line, so heights are measured along it exactly. It crosses the
// polar axis at (0, 0, -N e^2 sin(phi)), with N the prime-vertical radius of curvature.
//
// Poles and seam as in the spherical mapping (u = 0 at the poles, -180 on the seam). With f = 0
// this is a sphere of radius a and h = r - a.
#pragma once

#include <Eigen/Core>
#include <GeographicLib/Geocentric.hpp>
#include <cmath>
#include <string>

#include "qota/axial.hpp"
#include "qota/mapping.hpp"

namespace qota {

class GeodeticMapping {
 public:
  // a > 0 (metres), 0 <= f < 1 (oblate ellipsoids only); throws qota::Error otherwise.
  GeodeticMapping();  // WGS84
  GeodeticMapping(double a, double f);

  static constexpr const char* name() { return "geodetic"; }
  static constexpr bool kHeightUp = true;

  Eigen::Vector3d toMapped(const Eigen::Vector3d& world) const;
  Eigen::Vector3d toWorld(const Eigen::Vector3d& mapped) const;
  // Unit ellipsoid normal (up) at (u, v) degrees.
  static Eigen::Vector3d up(double u, double v);
  MappedLine line(double u, double v) const { return {toWorld({u, v, 0.0}), -up(u, v)}; }
  MappedDomain domain() const { return {-180.0, 180.0, -90.0, 90.0, true}; }
  std::string describe() const;                                 // "geodetic a=... f=..."
  static GeodeticMapping fromParameters(MappingParameters& p);  // WGS84 by default

  double a() const { return a_; }
  double f() const { return f_; }
  double e2() const { return e2_; }  // first eccentricity squared, f (2 - f)
  // Prime-vertical radius of curvature N at latitude v (degrees): the distance along the normal
  // from the surface to the polar axis.
  double primeVerticalRadius(double v) const;

  // As an axial mapping (axial.hpp): the local frame is the world (ECEF); the normal of latitude
  // v crosses the axis at s = -N e^2 sin(v), and h = t - N along it.
  static constexpr bool kPoles = true;
  static Eigen::Vector3d toLocal(const Eigen::Vector3d& world) { return world; }
  static Eigen::Vector3d fromLocal(const Eigen::Vector3d& local) { return local; }
  static Eigen::Vector3d directionToLocal(const Eigen::Vector3d& d) { return d; }
  static Eigen::Vector3d directionFromLocal(const Eigen::Vector3d& d) { return d; }
  AxialLine axialLine(double u, double v) const {
    double su, cu, sv, cv;
    axial::sinCosDegrees(u, su, cu);
    axial::sinCosDegrees(v, sv, cv);
    const double nprime = a_ / std::sqrt(1.0 - e2_ * sv * sv);
    return {-nprime * e2_ * sv, {cv * cu, cv * su, sv}, nprime};
  }
  double footprintHeight(const Eigen::Vector3d& world) const { return toMapped(world).z(); }
  void footprintV(const Eigen::Vector3d (&p)[3], const double (&h)[3], double scale, double& lo, double& hi) const;

 private:
  double a_, f_, e2_;
  GeographicLib::Geocentric earth_;
};

}  // namespace qota
