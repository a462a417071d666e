#include "qota/scene.hpp"

#include <cmath>
#include <limits>

#include "qota/error.hpp"

namespace qota {

std::size_t Scene::add(const TerrainIndex& index, const Eigen::Isometry3d& partToWorld,
                       std::string name) {
  parts_.push_back({&index, partToWorld, partToWorld.inverse(), std::move(name)});
  return parts_.size() - 1;
}

void Scene::setTransform(std::size_t part, const Eigen::Isometry3d& partToWorld) {
  if (part >= parts_.size()) {
    throw Error("scene: no part " + std::to_string(part) + " (the scene has " +
                std::to_string(parts_.size()) + ")");
  }
  if (!partToWorld.matrix().allFinite()) {
    throw Error("scene: the transform of part " + std::to_string(part) + " is not finite");
  }
  parts_[part].toWorld = partToWorld;
  parts_[part].fromWorld = partToWorld.inverse();
}

std::optional<SceneHit> Scene::nearest(const Eigen::Vector3d& p, bool below, bool top) const {
  const Eigen::Vector3d g = world_.gravity();
  const double hq = world_.toMapped(p).z();
  std::optional<SceneHit> best;
  for (std::size_t k = 0; k < parts_.size(); ++k) {
    const Part& part = parts_[k];
    const TerrainIndex& index = *part.index;
    const Eigen::Vector3d local = part.fromWorld * p;
    const Eigen::Vector3d localDown = part.fromWorld.linear() * g;
    // The part's candidates on the world line through p, as (part-frame hit, parameter along
    // the world's down from p).
    std::vector<Hit> hits;
    const Eigen::Vector3d own = index.mapping().gravity();
    if (localDown.cross(own).norm() <= 1e-15 && localDown.dot(own) > 0) {
      // Gravity kept: the part's own quadtree, with its own "all" (top to bottom).
      hits = index.allWorld(local);
    } else {
      for (const LineHit& lh : index.alongLine(local, localDown)) hits.push_back(lh.hit);
    }
    for (const Hit& h : hits) {
      SceneHit s;
      s.part = k;
      s.hit = h;
      s.hit.world = part.toWorld * h.world;
      s.hit.normal = (part.toWorld.linear() * h.normal).normalized();
      if (s.hit.normal.dot(g) > 0) s.hit.normal = -s.hit.normal;
      s.hit.height = world_.toMapped(s.hit.world).z();
      if (!top && (below ? !(s.hit.height <= hq) : !(s.hit.height >= hq))) continue;
      const bool better = !best || ((below || top) ? s.hit.height > best->hit.height
                                                   : s.hit.height < best->hit.height);
      if (better) best = s;  // ties keep the earlier part (and the part's own tie rule)
    }
  }
  return best;
}

std::optional<SceneHit> Scene::below(const Eigen::Vector3d& p) const { return nearest(p, true, false); }
std::optional<SceneHit> Scene::above(const Eigen::Vector3d& p) const { return nearest(p, false, false); }
std::optional<SceneHit> Scene::top(const Eigen::Vector3d& p) const { return nearest(p, true, true); }

}  // namespace qota
