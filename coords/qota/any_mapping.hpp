// AnyMapping: the runtime wrapper over every mapping, for tools and files. The hot paths take a
// concrete mapping type instead (see mapping.hpp).
#pragma once

#include <string>
#include <variant>

#include "qota/cartesian.hpp"
#include "qota/cylindrical.hpp"
#include "qota/geodetic.hpp"
#include "qota/spherical.hpp"

namespace qota {

static_assert(CoordinateMapping<CartesianMapping> && CoordinateMapping<SphericalMapping> &&
              CoordinateMapping<CylindricalMapping> && CoordinateMapping<GeodeticMapping>);

using AnyMapping = std::variant<CartesianMapping, SphericalMapping, CylindricalMapping, GeodeticMapping>;

// The mapping's describe() text: its name and parameters, "spherical centre=0,0,0".
std::string describe(const AnyMapping& mapping);

// Reads a describe() text back (exact round trip). Parameters may be omitted (defaults: gravity
// 0,0,-1 origin 0,0,0; centre 0,0,0; point 0,0,0 axis 0,0,1; WGS84 a and f) and appear in any
// order. Throws qota::Error naming the bad word.
AnyMapping parseMapping(const std::string& text);

const char* mappingName(const AnyMapping& mapping);
Eigen::Vector3d toMapped(const AnyMapping& mapping, const Eigen::Vector3d& world);
Eigen::Vector3d toWorld(const AnyMapping& mapping, const Eigen::Vector3d& mapped);
MappedLine lineOf(const AnyMapping& mapping, double u, double v);

}  // namespace qota
