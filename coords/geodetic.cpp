#include "qota/geodetic.hpp"

#include <GeographicLib/Constants.hpp>
#include <GeographicLib/Math.hpp>
#include <cmath>

#include "describe.hpp"
#include "qota/error.hpp"
#include "qota/spherical.hpp"

namespace qota {
namespace {

GeographicLib::Geocentric makeEarth(double a, double f) {
  if (!(a > 0.0) || !std::isfinite(a) || !(f >= 0.0) || !(f < 1.0)) {
    throw Error("geodetic mapping: need a > 0 and 0 <= f < 1, got a=" + detail::formatDouble(a) +
                " f=" + detail::formatDouble(f));
  }
  return GeographicLib::Geocentric(a, f);
}

}  // namespace

GeodeticMapping::GeodeticMapping()
    : GeodeticMapping(GeographicLib::Constants::WGS84_a(), GeographicLib::Constants::WGS84_f()) {}

GeodeticMapping::GeodeticMapping(double a, double f)
    : a_(a), f_(f), e2_(f * (2.0 - f)), earth_(makeEarth(a, f)) {}

Eigen::Vector3d GeodeticMapping::toMapped(const Eigen::Vector3d& world) const {
  if (!world.allFinite()) {
    throw Error("geodetic mapping: point (" + detail::formatVector(world) + ") is not finite");
  }
  double lat, lon, h;
  earth_.Reverse(world.x(), world.y(), world.z(), lat, lon, h);
  // GeographicLib returns longitude in [-180, 180]; the seam convention here is [-180, 180).
  if (world.x() == 0.0 && world.y() == 0.0) lon = 0.0;
  if (lon >= 180.0) lon -= 360.0;
  return {lon, lat, h};
}

Eigen::Vector3d GeodeticMapping::toWorld(const Eigen::Vector3d& mapped) const {
  double x, y, z;
  earth_.Forward(mapped.y(), mapped.x(), mapped.z(), x, y, z);
  return {x, y, z};
}

Eigen::Vector3d GeodeticMapping::up(double u, double v) {
  double su, cu, sv, cv;
  GeographicLib::Math::sincosd(u, su, cu);
  GeographicLib::Math::sincosd(v, sv, cv);
  return {cv * cu, cv * su, sv};
}

double GeodeticMapping::primeVerticalRadius(double v) const {
  double sv, cv;
  GeographicLib::Math::sincosd(v, sv, cv);
  return a_ / std::sqrt(1.0 - e2_ * sv * sv);
}

std::string GeodeticMapping::describe() const {
  return std::string(name()) + " a=" + detail::formatDouble(a_) + " f=" + detail::formatDouble(f_);
}

}  // namespace qota
