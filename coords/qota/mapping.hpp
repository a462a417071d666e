// The coordinate-mapping interface: the one place where a frame is defined.
//
// A mapping turns a world point into mapped coordinates (u, v, h): (u, v) picks one line of the
// preferred direction ("down", gravity or a light direction) and h is the position along it.
// The quadtree core works in (u, v) only; hits and heights are computed on the 3D polygons and
// the mapping's line, so they are exact whatever the mapping.
//
// Every mapping (cartesian.hpp, enu.hpp, spherical.hpp, cylindrical.hpp, geodetic.hpp) provides, at
// compile time for the hot paths:
//   name()                 "cartesian", "spherical", ...
//   toMapped(world)        world point -> (u, v, h); throws qota::Error where undefined
//   toWorld(mapped)        (u, v, h) -> world point
//   line(u, v)             the world line of (u, v): its point with h = 0 and its unit down
//   domain()               the (u, v) box and which axis is periodic
//   describe()             "name key=value ..." that parseMapping reads back (round trip)
//   fromParameters(params) the mapping from describe()'s key=value words (MappingParameters)
//   kHeightUp              true when h grows against down (up); false for the cylinder, whose
//                          h is the distance from the axis while down points away from it
// Planar mappings add frame() (planar.hpp), curved ones the axial interface (axial.hpp); the
// indexes are written once over those. AnyMapping (any_mapping.hpp) lists every mapping: adding
// one is its file and that line. coords/README.md catalogues every space.
#pragma once

#include <Eigen/Core>
#include <concepts>
#include <map>
#include <string>
#include <utility>

namespace qota {

// A line of a mapping in the world frame: origin + t * down, t real. origin is the point with
// h = 0 (the centre of a sphere, the axis point of a cylinder, the ellipsoid surface point).
struct MappedLine {
  Eigen::Vector3d origin;
  Eigen::Vector3d down;  // unit
};

// The (u, v) domain. When periodicU, u wraps: u and u + (uhi - ulo) are the same line, and the
// mapping normalizes u into [ulo, uhi).
struct MappedDomain {
  double ulo, uhi, vlo, vhi;
  bool periodicU;
};

// The key=value words of a describe() text, as a mapping's fromParameters reads them: each
// call takes its key out (the fallback when absent) and throws qota::Error naming a bad value;
// parseMapping then refuses any word no call took.
class MappingParameters {
 public:
  MappingParameters(std::string mapping, std::map<std::string, std::string> words)
      : mapping_(std::move(mapping)), words_(std::move(words)) {}
  Eigen::Vector3d vector(const char* key, const Eigen::Vector3d& fallback);  // "x,y,z"
  double number(const char* key, double fallback);
  const std::map<std::string, std::string>& left() const { return words_; }

 private:
  std::string mapping_;
  std::map<std::string, std::string> words_;
};

template <class M>
concept CoordinateMapping = requires(const M& m, const Eigen::Vector3d& p, double u, double v) {
  { M::name() } -> std::convertible_to<const char*>;
  { M::kHeightUp } -> std::convertible_to<bool>;
  { m.toMapped(p) } -> std::same_as<Eigen::Vector3d>;
  { m.toWorld(p) } -> std::same_as<Eigen::Vector3d>;
  { m.line(u, v) } -> std::same_as<MappedLine>;
  { m.domain() } -> std::same_as<MappedDomain>;
  { m.describe() } -> std::same_as<std::string>;
  { M::fromParameters(std::declval<MappingParameters&>()) } -> std::same_as<M>;
};

}  // namespace qota
