// The mapping registry: what the tools and Python know of each mapping when they take a source
// in it, one entry per alternative of AnyMapping, in its order (checked below at compile time).
// The tools' --mapping choices, help text and errors, Python's MAPPINGS and its checks, and
// openIndex's dispatch all read this list; adding a mapping to AnyMapping without an entry here,
// and without a way to place a raster and a mesh in it (source.cpp), fails the build.
#pragma once

#include <array>
#include <string>
#include <string_view>
#include <utility>
#include <variant>
#include <vector>

#include "qota/any_mapping.hpp"

namespace qota {

struct MappingEntry {
  const char* name;               ///< the mapping's name(): "cartesian", ...
  const char* raster;             ///< what a raster becomes in it
  const char* line;               ///< a query line's coordinates: "x y [z]"
  const char* answer;             ///< what the printed height is
  bool radius = false;            ///< takes a radius (a planet's, a station's)
  bool length = false;            ///< takes a length (a station's)
  bool origin = false;            ///< takes an origin (latitude, longitude, height)
  bool ellipsoid = false;         ///< a raster's heights are placed over an ellipsoid: a height reference
  bool lonLat = false;            ///< u is a longitude (any turn) and v a latitude in [-90, 90]
  bool ellipsoidHeights = false;  ///< answers are heights over the ellipsoid (or its geoid)
  bool map = false;               ///< u, v are a raster's map coordinates in its CRS, up the height
};

inline constexpr std::array<MappingEntry, 5> kMappingEntries{{
    {"cartesian", "the raster as a map", "x y [z]", "the height along up", false, false, false, false, false, false,
     true},
    {"spherical", "a lon/lat raster closed into a planet", "lon lat [r]", "the surface radius in metres", true, false,
     false, false, true, false, false},
    {"cylindrical", "the raster as a station's relief around the z axis", "angle axial [h]",
     "the distance from the axis in metres", true, true, false, false, false, false, false},
    {"geodetic", "a lon/lat raster on its CRS's ellipsoid", "lon lat [h]",
     "the height along the ellipsoid's normal, in the raster's vertical unit", false, false, false, true, true, true,
     false},
    {"enu", "the raster on its ellipsoid seen east-north-up at the origin", "east north [up]",
     "the terrain's up in metres", false, false, true, true, false, false, false},
}};

namespace detail {
template <std::size_t... I>
constexpr bool entriesFollowAnyMapping(std::index_sequence<I...>) {
  return ((std::string_view(kMappingEntries[I].name) == std::variant_alternative_t<I, AnyMapping>::name()) && ...);
}
}  // namespace detail
static_assert(kMappingEntries.size() == std::variant_size_v<AnyMapping>, "one registry entry per mapping");
static_assert(detail::entriesFollowAnyMapping(std::make_index_sequence<kMappingEntries.size()>()),
              "the registry lists AnyMapping's alternatives in their order");

/// The entry named `name` ("" is cartesian, the default). Throws qota::Error "mapping 'NAME' is
/// not one of cartesian, spherical, ...".
const MappingEntry& mappingEntry(std::string_view name);
/// Every mapping's name, in the registry's order.
std::vector<std::string> mappingNameList();
/// "cartesian (the raster as a map; lines 'x y [z]', prints the height along up), ...": the
/// tools' --mapping help, from the registry.
std::string mappingHelp();

/// "spherical or cylindrical": the mappings whose entry has `flag`, for messages.
std::string mappingsWith(bool MappingEntry::*flag);
/// Throws qota::Error "WHAT applies to the spherical or cylindrical mapping, not NAME" when an
/// option is given (`given`) to a mapping whose entry lacks `flag`. `what` names the option as
/// its caller's users spell it ("--radius" in the tools, "radius" in Python).
void requireMappingTakes(const MappingEntry& entry, bool given, bool MappingEntry::*flag, const std::string& what);

namespace detail {
template <std::size_t I, class F>
decltype(auto) withMappingAt(std::size_t at, F& f) {
  if constexpr (I + 1 < std::variant_size_v<AnyMapping>) {
    if (at != I) return withMappingAt<I + 1>(at, f);
  }
  return f.template operator()<std::variant_alternative_t<I, AnyMapping>>();
}
}  // namespace detail

/// Calls `f.template operator()<M>()` for the mapping type M named `name` ("" is cartesian) and
/// returns its result: the one place a mapping's name becomes its type.
template <class F>
decltype(auto) withMapping(std::string_view name, F&& f) {
  const MappingEntry& entry = mappingEntry(name);
  return detail::withMappingAt<0>(static_cast<std::size_t>(&entry - kMappingEntries.data()), f);
}

}  // namespace qota
