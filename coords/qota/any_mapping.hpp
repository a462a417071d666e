// AnyMapping: every mapping, in one list, and the runtime wrapper over them for tools and files
// (the hot paths take a concrete mapping type instead, see mapping.hpp). The list is the
// registration of a mapping: parseMapping, the indexes (AnyIndex: a planar or a curved index
// per mapping, lib/core/qota/any_index.hpp) and tree files (a mapping's kind is its place in the
// list: append, never reorder) all follow it.
#pragma once

#include <string>
#include <variant>

#include "qota/cartesian.hpp"
#include "qota/cylindrical.hpp"
#include "qota/enu.hpp"
#include "qota/geodetic.hpp"
#include "qota/planar.hpp"
#include "qota/spherical.hpp"

namespace qota {

using AnyMapping = std::variant<CartesianMapping, SphericalMapping, CylindricalMapping, GeodeticMapping, EnuMapping>;

// Every mapping is a coordinate mapping, and planar (planar.hpp) or axial (axial.hpp).
static_assert([]<class... M>(std::variant<M...>*) {
  return ((CoordinateMapping<M> && (PlanarMapping<M> != AxialMapping<M>)) && ...);
}(static_cast<AnyMapping*>(nullptr)));

// The mapping's describe() text: its name and parameters, "spherical centre=0,0,0".
std::string describe(const AnyMapping& mapping);

// Every mapping's name in AnyMapping's order, "cartesian, spherical, ... or enu", for messages.
std::string mappingNames();

// Reads a describe() text back (exact round trip). Parameters may be omitted (defaults: gravity
// 0,0,-1 origin 0,0,0; centre 0,0,0; point 0,0,0 axis 0,0,1; WGS84 a and f; lat, lon, h 0) and appear in any
// order. Throws qota::Error naming the bad word.
AnyMapping parseMapping(const std::string& text);

const char* mappingName(const AnyMapping& mapping);
Eigen::Vector3d toMapped(const AnyMapping& mapping, const Eigen::Vector3d& world);
Eigen::Vector3d toWorld(const AnyMapping& mapping, const Eigen::Vector3d& mapped);
MappedLine lineOf(const AnyMapping& mapping, double u, double v);

}  // namespace qota
