#include "qota/scene.hpp"

#include <cmath>
#include <limits>

#include "qota/error.hpp"

namespace qota {

void Scene::setTransform(std::size_t part, const Eigen::Isometry3d& partToWorld) {
  if (part >= parts_.size()) {
    throw Error("scene: no part " + std::to_string(part) + " (the scene has " + std::to_string(parts_.size()) + ")");
  }
  if (!partToWorld.matrix().allFinite()) {
    throw Error("scene: the transform of part " + std::to_string(part) + " is not finite");
  }
  parts_[part].toWorld = partToWorld;
  parts_[part].fromWorld = partToWorld.inverse();
}

namespace {

// Every hit of a part on the line (local point p, local down d), in the part's frame: along the
// part's own line through p when the world's line is that line (a fast query), else along any
// line (alongLine, exact, every index has it).
template <class Index>
std::vector<Hit> partHits(const Index& index, const Eigen::Vector3d& p, const Eigen::Vector3d& d) {
  const auto& mapping = index.mapping();
  const Eigen::Vector3d m = mapping.toMapped(p);
  const Eigen::Vector3d own = mapping.line(m.x(), m.y()).down;
  if (d.cross(own).norm() <= 1e-15 * d.norm() && d.dot(own) > 0) return index.allWorld(p);
  std::vector<Hit> hits;
  for (const LineHit& lh : index.alongLine(p, d)) hits.push_back(lh.hit);
  return hits;
}

}  // namespace

bool Scene::onWorldLine(const Eigen::Vector3d& x, const Eigen::Vector3d& down) const {
  Eigen::Vector3d m;
  try {
    m = toMapped(world_, x);
  } catch (const Error&) {
    return false;  // the world's singular point (a sphere's centre) is on no line
  }
  return lineOf(world_, m.x(), m.y()).down.dot(down) > 0;
}

std::optional<SceneHit> Scene::nearest(const Eigen::Vector3d& p, Want want) const {
  const bool up = std::visit([](const auto& m) { return m.kHeightUp; }, world_);
  const Eigen::Vector3d mp = toMapped(world_, p);
  const Eigen::Vector3d down = lineOf(world_, mp.x(), mp.y()).down;
  const double ep = up ? mp.z() : -mp.z();  // elevation: grows against down
  std::optional<SceneHit> best;
  double bestE = 0;
  for (std::size_t k = 0; k < parts_.size(); ++k) {
    const Part& part = parts_[k];
    const Eigen::Vector3d local = part.fromWorld * p;
    const Eigen::Vector3d localDown = part.fromWorld.linear() * down;
    const std::vector<Hit> hits =
        std::visit([&](const auto* index) { return partHits(*index, local, localDown); }, part.index);
    for (const Hit& h : hits) {
      SceneHit s;
      s.part = k;
      s.hit = h;
      s.hit.world = part.toWorld * h.world;
      // A line along any direction crosses a closed part twice, once on the far side of a curved
      // world's centre or axis: only the crossings on the world's own line through p count (the
      // world's line there runs the same way).
      if (!onWorldLine(s.hit.world, down)) continue;
      s.hit.normal = (part.toWorld.linear() * h.normal).normalized();
      if (s.hit.normal.dot(down) > 0) s.hit.normal = -s.hit.normal;
      s.hit.height = toMapped(world_, s.hit.world).z();
      const double e = up ? s.hit.height : -s.hit.height;
      if ((want == Want::Below && !(e <= ep)) || (want == Want::Above && !(e >= ep))) continue;
      const bool better = !best || (want == Want::Above ? e < bestE : e > bestE);
      if (better) best = s, bestE = e;  // ties keep the earlier part (and the part's own order)
    }
  }
  return best;
}

std::optional<SceneHit> Scene::below(const Eigen::Vector3d& p) const { return nearest(p, Want::Below); }
std::optional<SceneHit> Scene::above(const Eigen::Vector3d& p) const { return nearest(p, Want::Above); }
std::optional<SceneHit> Scene::top(const Eigen::Vector3d& p) const { return nearest(p, Want::Top); }

}  // namespace qota
