// The planar index's lines in any direction (terrain.hpp, alongLine).
#include "qota/terrain.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>
#include <string>
#include <thread>

#include "line_crossing.hpp"
#include "qota/predicates.hpp"

namespace qota {

std::vector<LineHit> PlanarCore::alongLine(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction, double tmin,
                                           double tmax) const {
  ensureTree();
  std::vector<LineHit> out;
  if (!origin.allFinite() || !direction.allFinite() || direction.squaredNorm() == 0) return out;  // no line
  // The line in mapped coordinates: O + t d.
  const Eigen::Vector3d O = frame_.toMapped(origin);
  const Eigen::Vector3d dn = frame_.directionToMapped(direction);
  // Only the part of the line inside the terrain's height slab can meet it.
  double t0 = tmin, t1 = tmax;
  if (dn.z() != 0) {
    double a = (hmin_ - O.z()) / dn.z(), b = (hmax_ - O.z()) / dn.z();
    if (a > b) std::swap(a, b);
    t0 = std::max(t0, a), t1 = std::min(t1, b);
  } else if (O.z() < hmin_ || O.z() > hmax_) {
    return out;
  }
  if (!(t0 <= t1)) return out;
  // The slab's piece of the line, projected, clipped to the tree's box (a horizontal line with
  // an unbounded t range is cut there).
  const Box2& box = tree_.box();
  auto clipAxis = [&](double o, double dd, double lo, double hi) {
    if (dd == 0) {
      if (o < lo || o > hi) t0 = 1, t1 = 0;
      return;
    }
    double a = (lo - o) / dd, b = (hi - o) / dd;
    if (a > b) std::swap(a, b);
    t0 = std::max(t0, a), t1 = std::min(t1, b);
  };
  clipAxis(O.x(), dn.x(), box.ulo, box.uhi);
  clipAxis(O.y(), dn.y(), box.vlo, box.vhi);
  if (!(t0 <= t1)) return out;
  std::vector<std::uint32_t> candidates;
  tree_.forLeavesAlong(
      O.x() + t0 * dn.x(), O.y() + t0 * dn.y(), O.x() + t1 * dn.x(), O.y() + t1 * dn.y(),
      [&](std::span<const std::uint32_t> items) { candidates.insert(candidates.end(), items.begin(), items.end()); });
  std::sort(candidates.begin(), candidates.end());
  candidates.erase(std::unique(candidates.begin(), candidates.end()), candidates.end());
  for (std::uint32_t t : candidates) {
    const Cold& c = cold_[t];
    double q[3][3];  // the corners' offsets from O (line_crossing.hpp)
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t v = c.corner[k];
      q[k][0] = corners2_[v].u - O.x(), q[k][1] = corners2_[v].v - O.y(), q[k][2] = cornerH_[v] - O.z();
    }
    detail::LineCrossing x;
    if (!detail::crossesTriangle(q, dn, x) || !(x.t >= tmin && x.t <= tmax)) continue;
    const double tt = x.t;
    Eigen::Vector3d n = x.normal;
    if (n.z() < 0) n = -n;
    LineHit lh;
    lh.t = tt;
    lh.hit.height = O.z() + tt * dn.z();
    lh.hit.world = origin + tt * direction;
    lh.hit.normal = frame_.directionToWorld(n.normalized());
    lh.hit.polygon = c.polygon;
    out.push_back(lh);
  }
  std::sort(out.begin(), out.end(),
            [](const LineHit& x, const LineHit& y) { return x.t != y.t ? x.t < y.t : x.hit.polygon < y.hit.polygon; });
  return out;
}

void PlanarCore::ensureNodeTops() const {
  ensureTree();
  if (deferred_->topsFor.load(std::memory_order_acquire) == generation_ + 1) return;
  const std::lock_guard<std::mutex> lock(deferred_->tops);
  if (deferred_->topsFor.load(std::memory_order_relaxed) == generation_ + 1) return;
  // Depth first from the root (a tree's depth is bounded by Maxdepth): a node's top is its
  // triangles' (a leaf) or its children's greatest.
  const auto nodes = tree_.nodes();
  std::vector<float> tops(nodes.size(), -INFINITY);
  const auto topOf = [&](const auto& self, std::uint32_t n) -> float {
    const Quadtree::Node& nd = nodes[n];
    float top = -INFINITY;
    if (nd.count == Quadtree::kInner) {
      for (std::uint32_t c = 0; c < 4; ++c) top = std::max(top, self(self, nd.first + c));
    } else {
      for (std::uint32_t t : tree_.leafRange(nd)) top = std::max(top, tris_[t].hhi);
    }
    return tops[n] = top;
  };
  if (!nodes.empty()) topOf(topOf, 0);
  nodeTops_ = std::move(tops);
  deferred_->topsFor.store(generation_ + 1, std::memory_order_release);
  const std::lock_guard<std::mutex> statsLock(deferred_->stats);
  treeStatsStale_ = true;  // the memory now counts the heights
}

std::uint32_t PlanarCore::segmentMeetsWhich(const Eigen::Vector3d& a, const Eigen::Vector3d& b, std::uint32_t endVertex,
                                            std::span<const std::uint32_t> skip) const {
  ensureNodeTops();
  const Eigen::Vector3d O = frame_.toMapped(a);
  const Eigen::Vector3d d = frame_.toMapped(b) - O;
  if (!O.allFinite() || !d.allFinite()) return kNoPolygon;
  // A node is passed over when the segment's lowest height over it is above its highest
  // triangle corner (hhi is rounded up), with a margin far above the rounding of t and h.
  const double margin = 1e-9 * (std::fabs(O.z()) + std::fabs(d.z())) + 1e-9;
  const auto enter = [&](std::uint32_t node, double t0, double t1) {
    const double top = nodeTops_[node];
    return !(O.z() + std::min(t0 * d.z(), t1 * d.z()) > top + 1e-12 * std::fabs(top) + 2 * margin);
  };
  std::uint32_t met = kNoPolygon;
  const auto meets = [&](std::span<const std::uint32_t> items) {
    for (std::uint32_t t : items) {
      const Cold& c = cold_[t];
      if (c.corner[0] == endVertex || c.corner[1] == endVertex || c.corner[2] == endVertex) continue;
      if (!skip.empty() && std::binary_search(skip.begin(), skip.end(), c.polygon)) continue;
      double q[3][3];  // the corners' offsets from O (line_crossing.hpp)
      for (int k = 0; k < 3; ++k) {
        const std::uint32_t v = c.corner[k];
        q[k][0] = corners2_[v].u - O.x(), q[k][1] = corners2_[v].v - O.y(), q[k][2] = cornerH_[v] - O.z();
      }
      if (detail::segmentMeetsTriangle(q, d)) {
        met = c.polygon;
        return true;
      }
    }
    return false;
  };
  tree_.walkAlong(O.x(), O.y(), O.x() + d.x(), O.y() + d.y(), enter, meets);
  return met;
}

}  // namespace qota
