#include "qota/geodetic.hpp"

#include <GeographicLib/Constants.hpp>
#include <GeographicLib/Math.hpp>
#include <algorithm>
#include <cmath>
#include <limits>

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

GeodeticMapping::GeodeticMapping(double a, double f) : a_(a), f_(f), e2_(f * (2.0 - f)), earth_(makeEarth(a, f)) {}

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

namespace {

// Geodetic latitude from the latitude chi of the axis-scaled point (x, y, z / (1 - e^2)) and the
// ratio k of their tangents (see footprintV).
double geodeticFromScaled(double chi, double k) {
  double s, c;
  GeographicLib::Math::sincosd(chi, s, c);
  return GeographicLib::Math::atan2d(s, k * c);
}

}  // namespace

void GeodeticMapping::footprintV(const Eigen::Vector3d (&p)[3], const double (&h)[3], double, double& lo,
                                 double& hi) const {
  // On the scaled points (x, y, z / (1 - e^2)) the geocentric latitude chi of a surface point is
  // its geodetic latitude phi, and a straight edge stays straight, so the arc extrema bound chi
  // exactly. Off the surface, tan(chi) = k tan(phi) with k = 1 + e^2 h / ((1 - e^2)(N + h)),
  // N in [a, a / sqrt(1 - e^2)]; phi is monotone in chi and in k, so the corners of the chi and
  // k ranges bound it. The triangle's heights lie between its lowest vertex minus its sag below
  // the ellipsoid (edge^2 / (8 radius of curvature), doubled) and its highest vertex (height is
  // convex).
  constexpr double kInf = std::numeric_limits<double>::infinity();
  const double e2 = e2_, a = a_;
  Eigen::Vector3d q[3];
  double hlo = kInf, hhi = -kInf, edge2 = 0;
  for (int i = 0; i < 3; ++i) {
    q[i] = Eigen::Vector3d(p[i].x(), p[i].y(), p[i].z() / (1.0 - e2));
    hlo = std::min(hlo, h[i]), hhi = std::max(hhi, h[i]);
    edge2 = std::max(edge2, (p[i] - p[(i + 1) % 3]).squaredNorm());
  }
  hlo -= edge2 / (4.0 * a * (1.0 - e2)) + 1e-9 * a;
  hhi += 1e-9 * a;
  double chiLo, chiHi;
  axial::latitudeRange(q, chiLo, chiHi);
  if (hlo <= -0.5 * a) {
    lo = -90.0, hi = 90.0;  // deep inside the ellipsoid: no useful bound
  } else {
    double kmin = kInf, kmax = -kInf;
    for (double hh : {hlo, hhi}) {
      for (double nn : {a, a / std::sqrt(1.0 - e2)}) {
        const double k = 1.0 + e2 * hh / ((1.0 - e2) * (nn + hh));
        kmin = std::min(kmin, k), kmax = std::max(kmax, k);
      }
    }
    lo = std::min(geodeticFromScaled(chiLo, kmin), geodeticFromScaled(chiLo, kmax));
    hi = std::max(geodeticFromScaled(chiHi, kmin), geodeticFromScaled(chiHi, kmax));
  }
  axial::padLatitudes(lo, hi);
}

GeodeticMapping GeodeticMapping::fromParameters(MappingParameters& p) {
  const double a = p.number("a", GeographicLib::Constants::WGS84_a());
  return GeodeticMapping(a, p.number("f", GeographicLib::Constants::WGS84_f()));
}

std::string GeodeticMapping::describe() const {
  return std::string(name()) + " a=" + detail::formatDouble(a_) + " f=" + detail::formatDouble(f_);
}

}  // namespace qota
