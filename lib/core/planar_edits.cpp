// The planar index's edits (terrain.hpp, the paper's dynamic insertion): a polygon inserted into
// the leaves it meets (the tree rebuilt when it grows the box), one removed from them.
#include "qota/terrain.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>
#include <string>
#include <thread>

#include "planar_answers.hpp"
#include "planar_arith.hpp"
#include "qota/error.hpp"

namespace qota {

void PlanarCore::rebuildTree(const Box2& domain) {
  // The single-layer check's edge bound (edgeView) holds for points within the domain: the new one.
  umax_ = std::max(std::fabs(domain.ulo), std::fabs(domain.uhi));
  vmax_ = std::max(std::fabs(domain.vlo), std::fabs(domain.vhi));
  std::vector<Box2> boxes(tris_.size());
  for (std::uint32_t t = 0; t < tris_.size(); ++t) {
    const Cold c = cold_[t];
    boxes[t] = makeRecord(t, Pending{{c.corner[0], c.corner[1], c.corner[2]}, c.polygon});
  }
  buildTreeOver(boxes, domain, tree_.options(), tree_.minSizeU(), tree_.minSizeV(), 1);
  stats_.domain = domain;
}

std::uint32_t PlanarCore::insertPolygon(std::span<const Eigen::Vector3d> corners) {
  ensureTree();
  generation_ = nextSerial();
  const auto id = static_cast<std::uint32_t>(stats_.polygons);
  if (corners.size() < 3) {
    throw Error("insertPolygon: a polygon needs at least 3 corners, got " + std::to_string(corners.size()));
  }
  if (corners2_.size() + corners.size() >= std::numeric_limits<std::uint32_t>::max()) {
    throw Error("insertPolygon: the index is full (32-bit vertex indices)");
  }
  std::vector<std::uint32_t> idx;
  const std::size_t firstVertex = corners2_.size();
  for (const Eigen::Vector3d& c : corners) {
    const Eigen::Vector3d m = frame_.toMapped(c);
    if (!c.allFinite() || !m.allFinite()) {
      corners2_.resize(firstVertex), cornerH_.resize(firstVertex);
      throw Error("insertPolygon: corner " + planar::describePoint(c) + " is not finite");
    }
    idx.push_back(static_cast<std::uint32_t>(corners2_.size()));
    corners2_.push_back({m.x(), m.y()});
    cornerH_.push_back(m.z());
  }
  std::vector<Pending> pending;
  try {
    fanPolygon(idx, id, pending);
  } catch (const Error&) {
    corners2_.resize(firstVertex), cornerH_.resize(firstVertex);
    throw;
  }
  ++stats_.polygons;
  stats_.vertices = corners2_.size();
  if (pending.empty()) {
    ++stats_.leftOut;
    return id;
  }
  // Grow the box (and rebuild the tree) when the polygon reaches outside it.
  Box2 domain = tree_.box().empty() ? Box2{INFINITY, INFINITY, -INFINITY, -INFINITY} : tree_.box();
  bool grows = tree_.box().empty();
  for (std::uint32_t v : idx) {
    const Point2 c = corners2_[v];
    if (!domain.contains(c.u, c.v)) grows = true;
    domain.ulo = std::min(domain.ulo, c.u), domain.uhi = std::max(domain.uhi, c.u);
    domain.vlo = std::min(domain.vlo, c.v), domain.vhi = std::max(domain.vhi, c.v);
  }
  const auto firstTri = static_cast<std::uint32_t>(tris_.size());
  for (const Pending& q : pending) {
    const auto t = static_cast<std::uint32_t>(tris_.size());
    tris_.emplace_back();
    cold_.emplace_back();
    makeRecord(t, q);
    hmin_ = std::min(hmin_, static_cast<double>(tris_[t].hlo));
    hmax_ = std::max(hmax_, static_cast<double>(tris_[t].hhi));
    ledger_.added(id, t);
  }
  stats_.triangles += pending.size();
  grid_.turnOff();  // an inserted polygon may overlap the grid: the quadtree answers from now on
  if (grows) {
    rebuildTree(domain);
  } else {
    for (auto t = firstTri; t < tris_.size(); ++t) {
      tree_.insert(
          t, [this](std::uint32_t i, const Box2& b) { return overlaps(i, boxOf(i), b); },
          [this](std::span<std::uint32_t> items) { return prepareLeaf(items); });
    }
  }
  treeStatsStale_ = true;
  return id;
}

bool PlanarCore::removePolygon(std::uint32_t polygon) {
  ensureTree();
  generation_ = nextSerial();
  const std::optional<std::size_t> triangles = ledger_.remove(
      polygon, stats_.polygons, cold_.size(), [this](std::size_t t) { return cold_[t].polygon; },
      [this](std::uint32_t t) {
        tree_.remove(t, [this](std::uint32_t i, const Box2& b) { return overlaps(i, boxOf(i), b); });
        --stats_.triangles;
        if (grid_.on()) grid_.clearSlot(cold_[t], t);
      });
  if (!triangles) return false;
  if (*triangles == 0) --stats_.leftOut;
  treeStatsStale_ = true;
  return true;
}

}  // namespace qota
