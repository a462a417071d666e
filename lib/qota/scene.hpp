// Scene: several terrains that move relative to each other (the paper's "several quadtrees for
// parts that move"): a ship's deck over the sea floor, a rotating platform in a hall. Each part
// is a built TerrainIndex in its own frame plus a rigid transform (part frame -> world) that may
// change every frame without a rebuild. A query follows the world's gravity and returns the
// nearest hit among all parts, with the part it came from.
//
// While a part's transform keeps its gravity (a turn about the vertical and any translation: a
// platform, a drifting raft), its own quadtree answers directly. When the transform tilts it (a
// rolling deck), the world's gravity is an oblique line in the part's frame and the part answers
// with TerrainIndex::alongLine, which walks its quadtree along the line's projection: still
// exact and watertight, a little slower. Walls (polygons with no area along the part's own
// gravity) are not in a part's index, so a tilted part's walls are not hit.
//
// Heights in the results are the world mapping's h. Not thread-safe while transforms change;
// queries alone may run in parallel.
#pragma once

#include <Eigen/Geometry>
#include <optional>
#include <string>
#include <vector>

#include "qota/terrain.hpp"

namespace qota {

struct SceneHit {
  Hit hit;              // world point, world normal, world height, the part's polygon id
  std::size_t part = 0;
};

class Scene {
 public:
  // The world's gravity and origin (heights of results are measured in this mapping).
  explicit Scene(const CartesianMapping& world = CartesianMapping()) : world_(world) {}

  // Adds a part; the index must outlive the scene. Returns the part's number.
  std::size_t add(const TerrainIndex& index,
                  const Eigen::Isometry3d& partToWorld = Eigen::Isometry3d::Identity(),
                  std::string name = {});
  void setTransform(std::size_t part, const Eigen::Isometry3d& partToWorld);
  const Eigen::Isometry3d& transform(std::size_t part) const { return parts_.at(part).toWorld; }
  const std::string& name(std::size_t part) const { return parts_.at(part).name; }
  std::size_t size() const { return parts_.size(); }

  // Nearest hit at or below (above) the world point along the world's gravity, over all parts;
  // equal heights go to the lower part number.
  std::optional<SceneHit> below(const Eigen::Vector3d& p) const;
  std::optional<SceneHit> above(const Eigen::Vector3d& p) const;
  std::optional<SceneHit> top(const Eigen::Vector3d& p) const;

 private:
  struct Part {
    const TerrainIndex* index;
    Eigen::Isometry3d toWorld;
    Eigen::Isometry3d fromWorld;
    std::string name;
  };
  std::optional<SceneHit> nearest(const Eigen::Vector3d& p, bool below, bool top) const;

  CartesianMapping world_;
  std::vector<Part> parts_;
};

}  // namespace qota
