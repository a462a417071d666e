// Scene: several terrains that move relative to each other (the paper's "several quadtrees for
// parts that move"): a ship's deck over the sea floor, a rotating platform in a hall, a section
// of a station turning about its axis. Each part is a built index in its own frame plus a rigid
// transform (part frame -> world) that may change every frame without a rebuild. A query
// follows the world mapping's line through the point (gravity, radial, along the ellipsoid
// normal, or outward in a station) and returns the nearest hit among all parts, with the part it
// came from.
//
// Parts take any transform: while it keeps the world's line on one of the part's own lines (a
// Cartesian part turned about its vertical and moved; a planet spinning about its centre), the
// part's quadtree answers directly; when it does not (a rolling deck; a raft on a planet, whose
// radial lines are not quite parallel; a planet moved off the world's centre), the part answers
// along the world's line with alongLine, still exact and watertight (a walk of the quadtree along
// the line's projection in a Cartesian part, a scan of its triangles in a curved one). Walls
// (polygons with no area along a Cartesian part's own gravity) are not in its index, so a tilted
// part's walls are not hit.
//
// Heights in the results are the world mapping's h; "below" is along the world's down. Not
// thread-safe while transforms change; queries alone may run in parallel.
#pragma once

#include <Eigen/Geometry>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "qota/any_mapping.hpp"
#include "qota/curved.hpp"
#include "qota/index.hpp"
#include "qota/terrain.hpp"

namespace qota {

struct SceneHit {
  Hit hit;  // world point, world normal (up), world height, the part's polygon id
  std::size_t part = 0;
};

class Scene {
 public:
  // The world's mapping: its lines are the queries' lines and its h the results' heights.
  explicit Scene(const AnyMapping& world = CartesianMapping()) : world_(world) {}

  // Adds a part; the index must outlive the scene. Returns the part's number.
  template <TerrainQuery Index>
  std::size_t add(const Index& index, const Eigen::Isometry3d& partToWorld = Eigen::Isometry3d::Identity(),
                  std::string name = {}) {
    parts_.push_back({&index, partToWorld, partToWorld.inverse(), std::move(name)});
    return parts_.size() - 1;
  }
  void setTransform(std::size_t part, const Eigen::Isometry3d& partToWorld);
  const Eigen::Isometry3d& transform(std::size_t part) const { return parts_.at(part).toWorld; }
  const std::string& name(std::size_t part) const { return parts_.at(part).name; }
  std::size_t size() const { return parts_.size(); }

  // Nearest hit at or below (above) the world point along the world's line, over all parts;
  // equal heights go to the lower part number.
  std::optional<SceneHit> below(const Eigen::Vector3d& p) const;
  std::optional<SceneHit> above(const Eigen::Vector3d& p) const;
  std::optional<SceneHit> top(const Eigen::Vector3d& p) const;

 private:
  bool onWorldLine(const Eigen::Vector3d& x, const Eigen::Vector3d& down) const;
  using AnyIndexPtr =
      std::variant<const CartesianIndex*, const SphericalIndex*, const CylindricalIndex*, const GeodeticIndex*>;
  struct Part {
    AnyIndexPtr index;
    Eigen::Isometry3d toWorld;
    Eigen::Isometry3d fromWorld;
    std::string name;
  };
  enum class Want { Below, Above, Top };
  std::optional<SceneHit> nearest(const Eigen::Vector3d& p, Want want) const;

  AnyMapping world_;
  std::vector<Part> parts_;
};

}  // namespace qota
