#include "qota/enu.hpp"

#include <GeographicLib/Constants.hpp>
#include <GeographicLib/Geocentric.hpp>
#include <GeographicLib/Math.hpp>
#include <cmath>

#include "describe.hpp"
#include "qota/error.hpp"

namespace qota {

using detail::formatDouble;

EnuMapping::EnuMapping(double lat0, double lon0, double h0)
    : EnuMapping(lat0, lon0, h0, GeographicLib::Constants::WGS84_a(), GeographicLib::Constants::WGS84_f()) {}

EnuMapping::EnuMapping(double lat0, double lon0, double h0, double a, double f)
    : lat0_(lat0), lon0_(lon0), h0_(h0), a_(a), f_(f) {
  if (!(lat0 >= -90.0 && lat0 <= 90.0) || !std::isfinite(lon0) || !std::isfinite(h0)) {
    throw Error("enu mapping: need -90 <= lat <= 90 and a finite lon and h, got lat=" + formatDouble(lat0) +
                " lon=" + formatDouble(lon0) + " h=" + formatDouble(h0));
  }
  if (!(a > 0.0) || !std::isfinite(a) || !(f >= 0.0) || !(f < 1.0)) {
    throw Error("enu mapping: need a > 0 and 0 <= f < 1, got a=" + formatDouble(a) + " f=" + formatDouble(f));
  }
  const GeographicLib::Geocentric earth(a, f);
  double x, y, z;
  earth.Forward(lat0, lon0, h0, x, y, z);
  // The rows east, north, up from degree-exact sines (sincosd: 90 degrees gives exactly 1 and 0).
  double sp, cp, sl, cl;
  GeographicLib::Math::sincosd(lat0, sp, cp);
  GeographicLib::Math::sincosd(lon0, sl, cl);
  frame_.rotation << -sl, cl, 0.0,  //
      -sp * cl, -sp * sl, cp,       //
      cp * cl, cp * sl, sp;
  frame_.origin = {x, y, z};
  frame_.identity = false;
}

EnuMapping EnuMapping::fromParameters(MappingParameters& p) {
  const double lat = p.number("lat", 0.0), lon = p.number("lon", 0.0), h = p.number("h", 0.0);
  const double a = p.number("a", GeographicLib::Constants::WGS84_a());
  return EnuMapping(lat, lon, h, a, p.number("f", GeographicLib::Constants::WGS84_f()));
}

std::string EnuMapping::describe() const {
  return std::string(name()) + " lat=" + formatDouble(lat0_) + " lon=" + formatDouble(lon0_) +
         " h=" + formatDouble(h0_) + " a=" + formatDouble(a_) + " f=" + formatDouble(f_);
}

}  // namespace qota
