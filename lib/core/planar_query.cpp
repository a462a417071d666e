// The planar index's single queries (terrain.hpp): the grid path's answers and the quadtree's,
// the hits they make, every polygon at a point, and the shadow test.
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
#include "qota/error.hpp"

namespace qota {

const PlanarCore::Tri& PlanarCore::gridRecord(std::uint32_t t, Tri& scratch) const {
  // A lean grid never reads the records, not even once the tree has made them: they may be
  // being made on another thread.
  if (!grid_.isLean()) return tris_[t];
  scratch = computeRecord(cold_[t].corner);
  return scratch;
}

PlanarCore::Tri PlanarCore::recordOf(std::uint32_t t) const {
  return grid_.isLean() || t >= tris_.size() ? computeRecord(cold_[t].corner) : tris_[t];
}

[[gnu::noinline]] std::uint32_t PlanarCore::gridAnswerFromRecords(double u, double v, double& h) const {
  Tri scratch;
  const Tri* rec = nullptr;
  const std::uint32_t t = gridTriangle(u, v, scratch, rec);
  if (t != kNoTriangle) h = heightOf(*rec, u, v);
  return t;
}

[[gnu::noinline]] std::uint32_t PlanarCore::gridAnswerNearEdge(double u, double v, double fc, double fr,
                                                               double& h) const {
  Tri scratch;
  const Tri* rec = nullptr;
  const std::uint32_t t = gridTriangleNearEdge(u, v, fc, fr, scratch, rec);
  if (t != kNoTriangle) h = heightOf(*rec, u, v);
  return t;
}

std::uint32_t PlanarCore::gridTriangle(double u, double v, Tri& scratch, const Tri*& rec) const {
  const detail::GridPath::Cell g = grid_.cell(u, v);
  if (g.inGrid) [[likely]] {
    const std::uint32_t t = grid_.triangleIn(g.slot);
    if (t != kNoTriangle) {
      // Clearly inside, beyond twice the edge tests' error bound: no other triangle of a grid
      // can hold the point.
      const Tri& r = gridRecord(t, scratch);
      rec = &r;
      const EdgeTest e = edgeTest(r, u, v);
      if (e.m > 2 * e.tol) return t;
    }
  }
  return gridTriangleNearEdge(u, v, g.fc, g.fr, scratch, rec);
}

std::uint32_t PlanarCore::gridTriangleNearEdge(double u, double v, double fc, double fr, Tri& scratch,
                                               const Tri*& rec) const {
  // The exact closed test decides among the triangles the grid says may hold the point, and the
  // smallest polygon id among those holding it answers, as in the quadtree's single-layer leaves.
  std::uint32_t best = kNoTriangle;
  grid_.forTrianglesNear(fc, fr, [&](std::uint32_t t) {
    Tri candidateScratch;
    const Tri& candidate = gridRecord(t, candidateScratch);
    if (!contains(candidate, t, u, v)) return;
    if (best == kNoTriangle || cold_[t].polygon < cold_[best].polygon) best = t, scratch = candidate;
  });
  rec = &scratch;
  return best;
}

bool PlanarCore::inside(std::uint32_t t, double u, double v) const {
  const Cold& c = cold_[t];
  const Point2 p{u, v};
  for (int k = 0; k < 3; ++k) {
    if (orient2dSign(corners2_[c.corner[k]], corners2_[c.corner[(k + 1) % 3]], p) < 0) return false;
  }
  return true;
}

// The nearest triangle at (u, v) on one side of z: Below = true finds the highest with h <= z,
// false the lowest with h >= z; equal heights go to the smaller polygon id.
//
// This is the hot loop. The leaf's triangle records are prefetched first, so their cache misses
// overlap instead of waiting on each other behind mispredicted branches; the per-triangle test
// then selects without branching on the data, except for the rare point within rounding of an
// edge, which takes the exact predicate.
template <bool Below>
std::uint32_t PlanarCore::nearest(double u, double v, double z, double& h, Cursor* cursor) const {
  if (grid_.on()) {
    const std::uint32_t t = gridAnswer<true>(u, v, h, cursor);
    return (Below ? h <= z : h >= z) ? t : kNoTriangle;
  }
  ensureTree();
  if (!tree_.contains(u, v)) return kNoTriangle;  // also rejects NaN
  // (On a walk, the records of a leaf ahead on its course are fetched as it enters a leaf.)
  const Quadtree::Node leaf =
      cursor ? tree_.leafNode(u, v, *cursor, [this](std::span<const std::uint32_t> ahead) { prefetchTriangles(ahead); })
             : tree_.leafNode(u, v);
  const bool single = Quadtree::singleLayer(leaf);
  if (cursor && single) {
    // A walk's next point is often in the last point's triangle. Clearly inside it (beyond the
    // edge tests' error bound), in a single-layer leaf, that triangle is the answer: it meets
    // the leaf, so the leaf references it, and no other triangle of the leaf can hold a point
    // of its interior. Its record is in cache, the leaf's others need not be read.
    Cursor::Memo& m = cursor->memo;
    if (m.key == kTreeMemo && m.owner == this && m.generation == generation_) {
      const Tri& r = tris_[m.item];
      const EdgeTest e = edgeTest(r, u, v);
      if (e.m > e.tol) {
        h = heightOf(r, u, v);
        return (Below ? h <= z : h >= z) ? m.item : kNoTriangle;
      }
    }
  }
  const auto items = tree_.leafRange(leaf);
  prefetchTriangles(items);
  const std::uint32_t t = nearestIn<Below>(items, single, u, v, z, h);
  if (cursor && single && t != kNoTriangle) {
    Cursor::Memo& m = cursor->memo;
    m.owner = this, m.generation = generation_, m.key = kTreeMemo, m.item = t;
  }
  return t;
}

Hit PlanarCore::makeHit(std::uint32_t t, double u, double v, double h) const {
  const Tri r = recordOf(t);
  Hit hit;
  hit.height = h;
  hit.world = frame_.toWorld(Eigen::Vector3d(u, v, h));
  hit.normal = frame_.directionToWorld(Eigen::Vector3d(-r.a, -r.b, 1.0).normalized());
  hit.polygon = cold_[t].polygon;
  return hit;
}

template <bool Below>
std::optional<Hit> PlanarCore::hitAt(double u, double v, double z, Cursor* cursor) const {
  double h = 0;
  const std::uint32_t t = nearest<Below>(u, v, z, h, cursor);
  if (t == kNoTriangle) return std::nullopt;
  return makeHit(t, u, v, h);
}

std::optional<Hit> PlanarCore::hitBelow(double u, double v, double z, Cursor* cursor) const {
  return hitAt<true>(u, v, z, cursor);
}

std::optional<Hit> PlanarCore::hitAbove(double u, double v, double z, Cursor* cursor) const {
  return hitAt<false>(u, v, z, cursor);
}

double PlanarCore::heightAt(double u, double v, double z, Cursor* cursor) const {
  if (!grid_.on()) return heightFromTree(u, v, z, cursor);
  double h = 0;  // no need for the triangle's id
  if (gridAnswer<false>(u, v, h, cursor) == kNoTriangle || !(h <= z)) return NAN;
  return h;
}

[[gnu::noinline]] double PlanarCore::heightFromTree(double u, double v, double z, Cursor* cursor) const {
  double h = 0;
  if (nearest<true>(u, v, z, h, cursor) == kNoTriangle) return NAN;
  return h;
}

std::vector<Hit> PlanarCore::all(double u, double v) const {
  ensureTree();
  std::vector<Hit> hits;
  if (!tree_.contains(u, v)) return hits;
  for (std::uint32_t t : tree_.leafItems(u, v)) {
    const Tri& r = tris_[t];
    if (!inside(t, u, v)) continue;  // rare call: the exact test alone is fine here
    hits.push_back(makeHit(t, u, v, heightOf(r, u, v)));
  }
  std::sort(hits.begin(), hits.end(), [](const Hit& a, const Hit& b) {
    return a.height != b.height ? a.height > b.height : a.polygon < b.polygon;
  });
  // A fanned polygon is met once: drop repeats from its fan triangles (on their shared diagonal).
  std::vector<Hit> unique;
  for (Hit& h : hits) {
    const bool seen = std::any_of(unique.begin(), unique.end(), [&](const Hit& k) { return k.polygon == h.polygon; });
    if (!seen) unique.push_back(std::move(h));
  }
  return unique;
}

bool PlanarCore::occludedAbove(double u, double v, double h, std::uint32_t vertex) const {
  ensureTree();
  if (!tree_.contains(u, v)) return false;
  for (std::uint32_t t : tree_.leafItems(u, v)) {
    if (triangleOccludesAbove(t, u, v, h, vertex)) return true;
  }
  return false;
}

bool PlanarCore::triangleOccludesAbove(std::uint32_t t, double u, double v, double h, std::uint32_t vertex) const {
  const Cold& c = cold_[t];
  if (c.corner[0] == vertex || c.corner[1] == vertex || c.corner[2] == vertex) return false;
  if (ledger_.removed(c.polygon)) return false;
  Tri scratch;
  const Tri& r = grid_.isLean() ? (scratch = computeRecord(c.corner)) : tris_[t];
  return contains(r, t, u, v) && heightOf(r, u, v) > h;
}

bool mappedTriangleAbove(const Eigen::Vector3d& c0, const Eigen::Vector3d& c1, const Eigen::Vector3d& c2, double u,
                         double v, double h) {
  // The corners counter-clockwise from the first, as fanPolygon orders them; inside() and
  // computeRecord's plane and height range, as heightOf uses them.
  const Point2 p0{c0.x(), c0.y()};
  Point2 p1{c1.x(), c1.y()}, p2{c2.x(), c2.y()};
  double h1 = c1.z(), h2 = c2.z();
  const int sign = orient2dSign(p0, p1, p2);
  if (sign == 0) return false;
  if (sign < 0) std::swap(p1, p2), std::swap(h1, h2);
  const Point2 q{u, v};
  if (orient2dSign(p0, p1, q) < 0 || orient2dSign(p1, p2, q) < 0 || orient2dSign(p2, p0, q) < 0) return false;
  const planar::PlaneFit f = planar::cornerPlane(p0.u, p0.v, c0.z(), p1.u, p1.v, h1, p2.u, p2.v, h2);
  const auto lo = static_cast<double>(floatBelow(std::min(c0.z(), std::min(h1, h2))));
  const auto hi = static_cast<double>(floatAbove(std::max(c0.z(), std::max(h1, h2))));
  return std::clamp(f.h0 + f.a * (u - p0.u) + f.b * (v - p0.v), lo, hi) > h;
}

std::uint32_t PlanarCore::testsAt(double u, double v) const {
  ensureTree();
  if (!tree_.contains(u, v)) return 0;
  return static_cast<std::uint32_t>(tree_.leafItems(u, v).size());
}

}  // namespace qota
