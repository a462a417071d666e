#include "triangulate.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <numeric>
#include <span>

#include "qota/predicates.hpp"

namespace qota::detail {
namespace {

// Plane geometry for convexity and ear clipping. A face is looked at in the coordinate plane it
// is most nearly parallel to; dropping a coordinate is exact, so orient2dSign decides every turn
// exactly on the file's own numbers.

struct Projection {
  int drop = 2;  // the axis left out: 0 keeps (y, z), 1 keeps (z, x), 2 keeps (x, y)
  Point2 operator()(const Eigen::Vector3d& p) const {
    switch (drop) {
      case 0:
        return {p.y(), p.z()};
      case 1:
        return {p.z(), p.x()};
      default:
        return {p.x(), p.y()};
    }
  }
};

// The axis along which the ring's shadow is largest: the largest component of the sum of its fan
// triangles' unsigned normals (summed relative to its first corner, so that map-sized coordinates
// do not swamp the small differences). Unsigned, so that a ring that crosses itself (whose signed
// normal can cancel out) still gets a plane in which the crossing shows.
Projection projectionFor(std::span<const std::uint32_t> ring, const std::vector<Eigen::Vector3d>& v) {
  Eigen::Vector3d n = Eigen::Vector3d::Zero();
  const Eigen::Vector3d& o = v[ring[0]];
  for (std::size_t i = 1; i + 1 < ring.size(); ++i) {
    n += (v[ring[i]] - o).cross(v[ring[i + 1]] - o).cwiseAbs();
  }
  Projection p;
  p.drop = n.x() >= n.y() && n.x() >= n.z() ? 0 : (n.y() >= n.z() ? 1 : 2);
  return p;
}

// Twice the signed area of a projected ring (shoelace, relative to its first corner), rounded:
// its sign orients rings (a ring whose sign this gets wrong has no area worth the name) and its
// size checks triangulations.
double signedArea2(const std::vector<Point2>& pts) {
  double a = 0;
  for (std::size_t i = 1; i + 1 < pts.size(); ++i) {
    a += (pts[i].u - pts[0].u) * (pts[i + 1].v - pts[0].v) - (pts[i].v - pts[0].v) * (pts[i + 1].u - pts[0].u);
  }
  return a;
}

int sgn(double x) { return (x > 0) - (x < 0); }

// Exact test that a counter-clockwise ring is convex: every turn is left or straight ahead (never
// a U-turn), and the edge directions go round once (their v component changes sign at most twice
// around the ring), which rules out star-shaped outlines that turn left all the way round twice.
bool convexCcw(const std::vector<Point2>& p) {
  const std::size_t n = p.size();
  int changesU = 0, changesV = 0, lastU = 0, lastV = 0, firstU = 0, firstV = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const Point2 a = p[(i + n - 1) % n], b = p[i], c = p[(i + 1) % n];
    const int turn = orient2dSign(a, b, c);
    if (turn < 0) return false;
    const int du = sgn(c.u - b.u), dv = sgn(c.v - b.v);  // exact signs of the edge b -> c
    if (du == 0 && dv == 0) return false;                // two corners on one point in this plane
    if (turn == 0 && (sgn(b.u - a.u) != du || sgn(b.v - a.v) != dv)) return false;  // U-turn
    if (du != 0) {
      if (lastU != 0 && du != lastU) ++changesU;
      if (firstU == 0) firstU = du;
      lastU = du;
    }
    if (dv != 0) {
      if (lastV != 0 && dv != lastV) ++changesV;
      if (firstV == 0) firstV = dv;
      lastV = dv;
    }
  }
  // Close the cycle: the last edge direction against the first.
  if (firstU != 0 && lastU != firstU) ++changesU;
  if (firstV != 0 && lastV != firstV) ++changesV;
  return changesU <= 2 && changesV <= 2;
}

struct Node {
  std::uint32_t id;  // mesh vertex
  Point2 p;          // projected position
};

// Does the direction from corner b towards x point into the polygon (strictly), given the ring's
// neighbours a -> b -> c with the interior on the left?
bool locallyInside(Point2 a, Point2 b, Point2 c, Point2 x) {
  const int turn = orient2dSign(a, b, c);
  const bool leftOfIn = orient2dSign(a, b, x) > 0, leftOfOut = orient2dSign(b, c, x) > 0;
  if (turn > 0) return leftOfIn && leftOfOut;
  if (turn < 0) return leftOfIn || leftOfOut;
  return leftOfIn;
}

// Can the bridge m -> p be drawn without touching any edge of the given rings (except where an
// edge merely starts at m or p)?
bool bridgeClear(const Node& m, const Node& p, const std::vector<const std::vector<Node>*>& rings) {
  for (const auto* ring : rings) {
    const std::size_t n = ring->size();
    for (std::size_t i = 0; i < n; ++i) {
      const Node& a = (*ring)[i];
      const Node& b = (*ring)[(i + 1) % n];
      const bool aShared = a.id == m.id || a.id == p.id, bShared = b.id == m.id || b.id == p.id;
      if (aShared && bShared) continue;
      if (!aShared && !bShared) {
        if (segmentsMeet(m.p, p.p, a.p, b.p)) return false;
        continue;
      }
      // The edge starts at an end of the bridge: they may only meet there, so they must not
      // overlap along one line.
      const Node& shared = aShared ? a : b;
      const Node& other = aShared ? b : a;
      const Node& far = shared.id == m.id ? p : m;
      if (orient2dSign(shared.p, far.p, other.p) == 0 && sgn(far.p.u - shared.p.u) == sgn(other.p.u - shared.p.u) &&
          sgn(far.p.v - shared.p.v) == sgn(other.p.v - shared.p.v)) {
        return false;
      }
    }
  }
  return true;
}

// Joins the holes (clockwise) to the outer ring (counter-clockwise) by bridges, giving one ring
// that walks along each bridge twice: the holes in order of their rightmost corner, each bridged
// from that corner to the nearest corner of the joined ring it can see (Eberly's argument: the
// ray to the right of that corner meets the joined ring first, so some corner of it is visible).
bool joinHoles(std::vector<Node>& outer, std::vector<std::vector<Node>> holes) {
  std::vector<std::size_t> order(holes.size());
  std::vector<std::size_t> rightmost(holes.size());
  for (std::size_t h = 0; h < holes.size(); ++h) {
    order[h] = h;
    rightmost[h] = 0;
    for (std::size_t i = 1; i < holes[h].size(); ++i) {
      const Point2 q = holes[h][i].p, r = holes[h][rightmost[h]].p;
      if (q.u > r.u || (q.u == r.u && q.v > r.v)) rightmost[h] = i;
    }
  }
  std::sort(order.begin(), order.end(),
            [&](std::size_t a, std::size_t b) { return holes[a][rightmost[a]].p.u > holes[b][rightmost[b]].p.u; });
  for (std::size_t k = 0; k < order.size(); ++k) {
    const auto& hole = holes[order[k]];
    const std::size_t mi = rightmost[order[k]];
    const Node m = hole[mi];
    const std::size_t hn = hole.size();
    // Rings still in the way: the joined ring and every hole not yet joined.
    std::vector<const std::vector<Node>*> rings{&outer};
    for (std::size_t j = k; j < order.size(); ++j) rings.push_back(&holes[order[j]]);
    // Candidates nearest first.
    std::vector<std::size_t> cand(outer.size());
    std::iota(cand.begin(), cand.end(), 0);
    auto dist2 = [&](std::size_t i) {
      const double du = outer[i].p.u - m.p.u, dv = outer[i].p.v - m.p.v;
      return du * du + dv * dv;
    };
    std::sort(cand.begin(), cand.end(), [&](std::size_t a, std::size_t b) { return dist2(a) < dist2(b); });
    const std::size_t on = outer.size();
    // A corner the hole shares with the joined ring (holes that touch) is a last resort: a bridge
    // to it would visit that point three times, which ear clipping handles badly.
    std::vector<std::uint32_t> holeIds;
    for (const Node& h : hole) holeIds.push_back(h.id);
    std::sort(holeIds.begin(), holeIds.end());
    std::stable_partition(cand.begin(), cand.end(), [&](std::size_t i) {
      return !std::binary_search(holeIds.begin(), holeIds.end(), outer[i].id);
    });
    bool joined = false;
    for (std::size_t i : cand) {
      const Node& p = outer[i];
      if (p.id == m.id) continue;
      if (!locallyInside(outer[(i + on - 1) % on].p, p.p, outer[(i + 1) % on].p, m.p)) continue;
      if (!locallyInside(hole[(mi + hn - 1) % hn].p, m.p, hole[(mi + 1) % hn].p, p.p)) continue;
      if (!bridgeClear(m, p, rings)) continue;
      // ... p, m, (the hole from m round to m), m, p, ...
      std::vector<Node> splice;
      splice.reserve(hn + 2);
      for (std::size_t j = 0; j <= hn; ++j) splice.push_back(hole[(mi + j) % hn]);
      splice.push_back(p);
      outer.insert(outer.begin() + static_cast<std::ptrdiff_t>(i + 1), splice.begin(), splice.end());
      joined = true;
      break;
    }
    if (!joined) return false;
  }
  return true;
}

// Ear clipping of a counter-clockwise ring (possibly with bridges, whose corners appear twice,
// and holes that touch), with exact tests. An ear is a strictly convex corner whose triangle holds
// no other corner (on its boundary included, so that no corner is left on an edge of a triangle:
// a T-junction). When a whole round finds no ear, a corner that is straight ahead is removed (a
// T-junction, but the only way on); when there is none, the ring is not simple and false is
// returned. Quadratic in the corners (cubic at worst): fine for building and parcel outlines, slow
// for outlines of tens of thousands of corners.
bool earClip(const std::vector<Node>& ring, std::vector<std::array<std::uint32_t, 3>>& out) {
  const std::size_t n = ring.size();
  std::vector<std::size_t> prev(n), next(n);
  for (std::size_t i = 0; i < n; ++i) {
    prev[i] = (i + n - 1) % n;
    next[i] = (i + 1) % n;
  }
  auto unlink = [&](std::size_t i) {
    next[prev[i]] = next[i];
    prev[next[i]] = prev[i];
  };
  auto isEar = [&](std::size_t b) {
    const std::size_t a = prev[b], c = next[b];
    const Node &A = ring[a], &B = ring[b], &C = ring[c];
    if (orient2dSign(A.p, B.p, C.p) <= 0) return false;
    for (std::size_t k = next[c]; k != a; k = next[k]) {
      const Node& K = ring[k];
      const int ab = orient2dSign(A.p, B.p, K.p), bc = orient2dSign(B.p, C.p, K.p), ca = orient2dSign(C.p, A.p, K.p);
      if (K.id != A.id && K.id != B.id && K.id != C.id) {
        if (ab >= 0 && bc >= 0 && ca >= 0) return false;
        continue;
      }
      // K is the other visit of a corner (where the ring touches itself: a bridge end, or holes
      // that meet at a point). No corner need lie inside the triangle for the ring's edges at
      // that visit to cross it, so look at them: neither may point into the triangle's angle at
      // that corner, and the triangle's new edge A-C may not point into the ring's angle there.
      const Point2 before = ring[prev[k]].p, after = ring[next[k]].p;
      auto intoCorner = [&](Point2 x) {
        if (K.id == A.id) return orient2dSign(A.p, B.p, x) > 0 && orient2dSign(C.p, A.p, x) > 0;
        if (K.id == B.id) return orient2dSign(B.p, C.p, x) > 0 && orient2dSign(A.p, B.p, x) > 0;
        return orient2dSign(C.p, A.p, x) > 0 && orient2dSign(B.p, C.p, x) > 0;
      };
      if (intoCorner(before) || intoCorner(after)) return false;
      if (K.id == A.id && locallyInside(before, K.p, after, C.p)) return false;
      if (K.id == C.id && locallyInside(before, K.p, after, A.p)) return false;
    }
    return true;
  };
  // A corner where the ring doubles back on itself (the tip of a zero-width spike, such as what is
  // left of a bridge once the hole beyond it is cut away) or repeats the point before it encloses
  // nothing: it goes at once, since a spike makes corners elsewhere look like ears that lie
  // outside the polygon.
  auto spike = [&](std::size_t b) {
    const Node &A = ring[prev[b]], &B = ring[b], &C = ring[next[b]];
    if (B.id == A.id || B.id == C.id) return true;
    return orient2dSign(A.p, B.p, C.p) == 0 && sgn(A.p.u - B.p.u) == sgn(C.p.u - B.p.u) &&
           sgn(A.p.v - B.p.v) == sgn(C.p.v - B.p.v);
  };
  std::vector<char> linked(n, 1);
  std::size_t remaining = n, cur = 0, misses = 0;
  auto drop = [&](std::size_t i) {
    unlink(i);
    linked[i] = 0;
    --remaining;
  };
  // Removes the spike tips among `check`, and those their removal makes, keeping `cur` in the
  // ring. Run after every change, so that isEar never sees a spike anywhere in the ring.
  std::vector<std::size_t> check(n);
  std::iota(check.begin(), check.end(), 0);
  auto prune = [&] {
    while (!check.empty() && remaining > 2) {
      const std::size_t b = check.back();
      check.pop_back();
      if (!linked[b] || !spike(b)) continue;
      const std::size_t a = prev[b], c = next[b];
      drop(b);
      if (cur == b) cur = a;
      check.push_back(a);
      check.push_back(c);
    }
    check.clear();
  };
  prune();
  while (remaining > 3) {
    if (isEar(cur)) {
      const std::size_t a = prev[cur], c = next[cur];
      out.push_back({ring[a].id, ring[cur].id, ring[c].id});
      drop(cur);
      cur = c;
      misses = 0;
      check = {a, c};
      prune();
      continue;
    }
    cur = next[cur];
    if (++misses <= remaining) continue;
    bool removed = false;
    for (std::size_t k = 0, i = cur; k < remaining; ++k, i = next[i]) {
      if (orient2dSign(ring[prev[i]].p, ring[i].p, ring[next[i]].p) == 0) {
        const std::size_t a = prev[i], c = next[i];
        drop(i);
        cur = c;
        check = {a, c};
        prune();
        removed = true;
        break;
      }
    }
    if (!removed) return false;
    misses = 0;
  }
  if (remaining == 3) {
    const std::size_t a = prev[cur], c = next[cur];
    if (orient2dSign(ring[a].p, ring[cur].p, ring[c].p) > 0) out.push_back({ring[a].id, ring[cur].id, ring[c].id});
  }
  return true;
}

// Ear clipping a ring that crosses itself ends with triangles that overlap or leave gaps: their
// area then differs from the polygon's (a bow tie's signed area is nothing at all).
bool coversArea(const std::vector<std::array<std::uint32_t, 3>>& tris, const std::vector<std::uint32_t>& outline,
                const std::vector<std::vector<std::uint32_t>>& holes, const Projection& proj,
                const std::vector<Eigen::Vector3d>& v) {
  auto area = [&](const std::vector<std::uint32_t>& ring) {
    std::vector<Point2> pts;
    pts.reserve(ring.size());
    for (std::uint32_t id : ring) pts.push_back(proj(v[id]));
    return std::fabs(signedArea2(pts));
  };
  double polygon = area(outline), cut = 0;
  for (const auto& h : holes) polygon -= area(h);
  for (const auto& t : tris) cut += area({t[0], t[1], t[2]});
  // Both sums are rounded; allow for that, also in long thin polygons whose area is small next
  // to their squared size (the scale of each rounding error).
  Point2 lo{INFINITY, INFINITY}, hi{-INFINITY, -INFINITY};
  for (std::uint32_t id : outline) {
    const Point2 q = proj(v[id]);
    lo = {std::min(lo.u, q.u), std::min(lo.v, q.v)}, hi = {std::max(hi.u, q.u), std::max(hi.v, q.v)};
  }
  const double size2 = (hi.u - lo.u) * (hi.u - lo.u) + (hi.v - lo.v) * (hi.v - lo.v);
  std::size_t corners = outline.size();
  for (const auto& h : holes) corners += h.size();
  const double tolerance = 1e-9 * (cut + std::fabs(polygon)) + 1e-14 * static_cast<double>(corners) * size2;
  return !tris.empty() && std::fabs(cut - polygon) <= tolerance;
}

}  // namespace

// Exact: are the three points on one line in 3D? (All three coordinate-plane shadows collinear.)
bool collinear3(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  for (int drop = 0; drop < 3; ++drop) {
    const Projection p{drop};
    if (orient2dSign(p(a), p(b), p(c)) != 0) return false;
  }
  return true;
}

FaceCut cutFace(const std::vector<std::uint32_t>& outline, const std::vector<std::vector<std::uint32_t>>& holes,
                const std::vector<Eigen::Vector3d>& v, bool keepConvex) {
  if (outline.size() == 3 && holes.empty()) return {FaceCut::whole, {}};

  const Projection proj = projectionFor(outline, v);
  auto nodes = [&](const std::vector<std::uint32_t>& ring, bool ccw) {
    std::vector<Node> ns;
    ns.reserve(ring.size());
    std::vector<Point2> pts;
    for (std::uint32_t id : ring) ns.push_back({id, proj(v[id])}), pts.push_back(ns.back().p);
    if ((signedArea2(pts) > 0) != ccw) std::reverse(ns.begin(), ns.end());
    return ns;
  };
  std::vector<Node> outer = nodes(outline, true);
  if (holes.empty() && keepConvex) {
    std::vector<Point2> pts;
    pts.reserve(outer.size());
    for (const Node& node : outer) pts.push_back(node.p);
    if (convexCcw(pts)) return {FaceCut::whole, {}};
  }

  std::vector<std::vector<Node>> holeNodes;
  holeNodes.reserve(holes.size());
  for (const auto& h : holes) holeNodes.push_back(nodes(h, false));
  if (!holeNodes.empty() && !joinHoles(outer, std::move(holeNodes))) {
    return {FaceCut::holesNotJoined, {}};
  }
  std::vector<std::array<std::uint32_t, 3>> tris;
  if (!earClip(outer, tris) || !coversArea(tris, outline, holes, proj, v)) {
    return {FaceCut::notSimple, {}};
  }
  return {FaceCut::triangles, std::move(tris)};
}

}  // namespace qota::detail
