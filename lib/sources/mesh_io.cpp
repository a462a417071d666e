#include "qota/mesh_io.hpp"

#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <cpl_error.h>
#include <gdal_priv.h>
#include <ogr_geometry.h>
#include <ogr_spatialref.h>
#include <ogrsf_frmts.h>

#include <Eigen/Geometry>
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <array>
#include <assimp/Importer.hpp>
#include <bit>
#include <cctype>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <limits>
#include <memory>
#include <numeric>
#include <span>
#include <unordered_map>

#include "qota/dem.hpp"  // ensureGdalRegistered
#include "gdal_errors.hpp"
#include "qota/error.hpp"
#include "qota/predicates.hpp"

namespace qota {
namespace {

// Single-precision Assimp is what the header's precision note is about; if a double build shows
// up, the note (and MeshFile::singlePrecision) must say so, and OBJ could go through it too.
constexpr bool kAssimpSinglePrecision = sizeof(ai_real) == sizeof(float);
// The largest coordinate a mesh may have (see Builder::vertex).
constexpr double kMaxCoordinate = 1e100;

// ---------------------------------------------------------------------------------------------
// Vertex sharing: one vertex per exact coordinate triple.

struct PointKey {
  double x, y, z;
  bool operator==(const PointKey&) const = default;  // -0 == +0, as wanted
};

struct PointHash {
  std::size_t operator()(const PointKey& k) const {
    // Adding 0.0 turns -0 into +0, so that equal keys hash equally.
    std::uint64_t h = 0xcbf29ce484222325ull;
    for (double d : {k.x + 0.0, k.y + 0.0, k.z + 0.0}) {
      h ^= std::bit_cast<std::uint64_t>(d);
      h *= 0x100000001b3ull;
      h ^= h >> 29;
    }
    return static_cast<std::size_t>(h);
  }
};

// ---------------------------------------------------------------------------------------------
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
Projection projectionFor(std::span<const std::uint32_t> ring,
                         const std::vector<Eigen::Vector3d>& v) {
  Eigen::Vector3d n = Eigen::Vector3d::Zero();
  const Eigen::Vector3d o = v[ring[0]];
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
    a += (pts[i].u - pts[0].u) * (pts[i + 1].v - pts[0].v) -
         (pts[i].v - pts[0].v) * (pts[i + 1].u - pts[0].u);
  }
  return a;
}

int sgn(double x) { return (x > 0) - (x < 0); }

// Exact: are the three points on one line in 3D? (All three coordinate-plane shadows collinear.)
bool collinear3(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  for (int drop = 0; drop < 3; ++drop) {
    const Projection p{drop};
    if (orient2dSign(p(a), p(b), p(c)) != 0) return false;
  }
  return true;
}

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

// Do segments ab and cd meet (closed segments, exact)?
bool onSegment(Point2 a, Point2 b, Point2 p) {  // p collinear with ab: within its box?
  return std::min(a.u, b.u) <= p.u && p.u <= std::max(a.u, b.u) && std::min(a.v, b.v) <= p.v &&
         p.v <= std::max(a.v, b.v);
}
bool segmentsMeet(Point2 a, Point2 b, Point2 c, Point2 d) {
  const int d1 = orient2dSign(c, d, a), d2 = orient2dSign(c, d, b);
  const int d3 = orient2dSign(a, b, c), d4 = orient2dSign(a, b, d);
  if (d1 * d2 < 0 && d3 * d4 < 0) return true;
  return (d1 == 0 && onSegment(c, d, a)) || (d2 == 0 && onSegment(c, d, b)) ||
         (d3 == 0 && onSegment(a, b, c)) || (d4 == 0 && onSegment(a, b, d));
}

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
      if (orient2dSign(shared.p, far.p, other.p) == 0 &&
          sgn(far.p.u - shared.p.u) == sgn(other.p.u - shared.p.u) &&
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
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return holes[a][rightmost[a]].p.u > holes[b][rightmost[b]].p.u;
  });
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
    std::sort(cand.begin(), cand.end(),
              [&](std::size_t a, std::size_t b) { return dist2(a) < dist2(b); });
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
      outer.insert(outer.begin() + static_cast<std::ptrdiff_t>(i + 1), splice.begin(),
                   splice.end());
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
      const int ab = orient2dSign(A.p, B.p, K.p), bc = orient2dSign(B.p, C.p, K.p),
                ca = orient2dSign(C.p, A.p, K.p);
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
    if (orient2dSign(ring[a].p, ring[cur].p, ring[c].p) > 0)
      out.push_back({ring[a].id, ring[cur].id, ring[c].id});
  }
  return true;
}

// ---------------------------------------------------------------------------------------------
// Collects vertices, polygons and their names for every reader.

class Builder {
 public:
  using Where = std::function<std::string()>;  // describes the face for messages, on demand

  Builder(MeshFile& out, const MeshFileOptions& options) : out_(out), options_(options) {}

  std::uint32_t vertex(const Eigen::Vector3d& p) {
    // Coordinates whose products stay in the range of doubles (the exact predicates multiply
    // coordinate differences): finite and within 1e100 in magnitude.
    if (!(p.cwiseAbs().maxCoeff() <= kMaxCoordinate)) {
      throw Error(out_.path + ": vertex " + std::to_string(out_.mesh.vertices.size() + 1) + " (" +
                  std::to_string(p.x()) + ", " + std::to_string(p.y()) + ", " + std::to_string(p.z()) +
                  ") is not finite or beyond 1e100; shift the model to a local origin");
    }
    const auto [it, added] = ids_.try_emplace(
        PointKey{p.x(), p.y(), p.z()}, static_cast<std::uint32_t>(out_.mesh.vertices.size()));
    if (added) {
      if (out_.mesh.vertices.size() >= std::numeric_limits<std::uint32_t>::max() - 1) {
        throw Error(out_.path + ": more than 2^32 - 2 vertices; split the file");
      }
      out_.mesh.vertices.push_back(p);
    }
    return it->second;
  }

  std::uint32_t material(const std::string& name) {
    return named(name, materialIds_, out_.materials);
  }
  std::uint32_t object(const std::string& name) { return named(name, objectIds_, out_.objects); }

  // rings[0] is the outline, any further rings are holes. Corners are mesh vertex indices.
  void addFace(std::vector<std::vector<std::uint32_t>> rings, std::uint32_t material,
               std::uint32_t object, std::uint64_t source, const Where& where) {
    const auto& v = out_.mesh.vertices;
    std::vector<std::uint32_t> raw;
    if (options_.keepDegenerate) raw = rings[0];
    for (auto& ring : rings) dropRepeats(ring);

    if (degenerate(rings[0])) {
      ++out_.degenerate;
      if (options_.keepDegenerate && raw.size() >= 3) emit(raw, material, object, source);
      return;
    }
    const std::vector<std::uint32_t>& outline = rings[0];
    // Holes with no area cut nothing out.
    std::vector<std::vector<std::uint32_t>> holes;
    for (std::size_t r = 1; r < rings.size(); ++r) {
      if (!degenerate(rings[r])) holes.push_back(std::move(rings[r]));
    }
    if (outline.size() == 3 && holes.empty()) {
      emit(outline, material, object, source);
      return;
    }

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
    if (holes.empty() && !options_.triangulate) {
      std::vector<Point2> pts;
      for (const Node& node : outer) pts.push_back(node.p);
      if (convexCcw(pts)) {
        emit(outline, material, object, source);
        return;
      }
    }

    std::vector<std::vector<Node>> holeNodes;
    for (const auto& h : holes) holeNodes.push_back(nodes(h, false));
    if (!holeNodes.empty() && !joinHoles(outer, std::move(holeNodes))) {
      throw Error(where() +
                  ": cannot join the polygon's holes to its outline (a hole outside it, "
                  "or rings that cross)");
    }
    std::vector<std::array<std::uint32_t, 3>> tris;
    if (!earClip(outer, tris) || !coversArea(tris, outline, holes, proj)) {
      throw Error(where() + ": cannot cut the " + std::to_string(outline.size()) +
                  "-corner polygon into triangles: its outline crosses itself" +
                  (holes.empty() ? "" : " or its holes"));
    }
    ++out_.triangulated;
    for (const auto& t : tris) emit(t, material, object, source);
  }

  // Ear clipping a ring that crosses itself ends with triangles that overlap or leave gaps: their
  // area then differs from the polygon's (a bow tie's signed area is nothing at all).
  bool coversArea(const std::vector<std::array<std::uint32_t, 3>>& tris,
                  const std::vector<std::uint32_t>& outline,
                  const std::vector<std::vector<std::uint32_t>>& holes,
                  const Projection& proj) const {
    const auto& v = out_.mesh.vertices;
    auto area = [&](const std::vector<std::uint32_t>& ring) {
      std::vector<Point2> pts;
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
      lo = {std::min(lo.u, q.u), std::min(lo.v, q.v)},
      hi = {std::max(hi.u, q.u), std::max(hi.v, q.v)};
    }
    const double size2 = (hi.u - lo.u) * (hi.u - lo.u) + (hi.v - lo.v) * (hi.v - lo.v);
    std::size_t corners = outline.size();
    for (const auto& h : holes) corners += h.size();
    const double tolerance =
        1e-9 * (cut + std::fabs(polygon)) + 1e-14 * static_cast<double>(corners) * size2;
    return !tris.empty() && std::fabs(cut - polygon) <= tolerance;
  }

  // The origin, and the one check every reader shares: there is something to query.
  void finish() {
    if (out_.mesh.polygonCount() == 0) {
      throw Error(out_.path + ": no polygons" +
                  (out_.degenerate ? " (all " + std::to_string(out_.degenerate) +
                                         " faces are degenerate: no area)"
                                   : std::string()));
    }
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
    Eigen::Vector3d hi = -lo;
    for (const auto& p : out_.mesh.vertices) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
    out_.origin = 0.5 * lo + 0.5 * hi;
  }

 private:
  static std::uint32_t named(const std::string& name,
                             std::unordered_map<std::string, std::uint32_t>& ids,
                             std::vector<std::string>& names) {
    const auto [it, added] = ids.try_emplace(name, static_cast<std::uint32_t>(names.size()));
    if (added) names.push_back(name);
    return it->second;
  }

  // Removes repeated consecutive corners, the closing repeat of the first corner included.
  static void dropRepeats(std::vector<std::uint32_t>& ring) {
    ring.erase(std::unique(ring.begin(), ring.end()), ring.end());
    while (ring.size() > 1 && ring.front() == ring.back()) ring.pop_back();
  }

  // Fewer than three distinct corners, or all exactly on one line.
  bool degenerate(const std::vector<std::uint32_t>& ring) const {
    if (ring.size() < 3) return true;
    const auto& v = out_.mesh.vertices;
    const std::uint32_t a = ring[0], b = ring[1];  // distinct after dropRepeats
    for (std::size_t i = 2; i < ring.size(); ++i) {
      if (ring[i] != a && ring[i] != b && !collinear3(v[a], v[b], v[ring[i]])) return false;
    }
    return true;
  }

  void emit(std::span<const std::uint32_t> corners, std::uint32_t material, std::uint32_t object,
            std::uint64_t source) {
    if (corners.size() == 3) {
      out_.mesh.addTriangle(corners[0], corners[1], corners[2]);
    } else {
      out_.mesh.addPolygon(corners);
    }
    out_.polygonMaterial.push_back(material);
    out_.polygonObject.push_back(object);
    out_.polygonSource.push_back(source);
  }

  MeshFile& out_;
  const MeshFileOptions& options_;
  std::unordered_map<PointKey, std::uint32_t, PointHash> ids_;
  std::unordered_map<std::string, std::uint32_t> materialIds_, objectIds_;
};

// ---------------------------------------------------------------------------------------------
// Wavefront OBJ, in double precision.

std::string_view trim(std::string_view s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.front()))) s.remove_prefix(1);
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.remove_suffix(1);
  return s;
}

std::vector<std::string_view> tokens(std::string_view s) {
  std::vector<std::string_view> out;
  std::size_t i = 0;
  while (i < s.size()) {
    while (i < s.size() && std::isspace(static_cast<unsigned char>(s[i]))) ++i;
    const std::size_t b = i;
    while (i < s.size() && !std::isspace(static_cast<unsigned char>(s[i]))) ++i;
    if (i > b) out.push_back(s.substr(b, i - b));
  }
  return out;
}

class ObjReader {
 public:
  ObjReader(MeshFile& out, const MeshFileOptions& options) : out_(out), builder_(out, options) {}

  void read() {
    std::ifstream in(out_.path, std::ios::binary);
    if (!in) throw Error(out_.path + ": cannot open for reading");
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (in.bad()) throw Error(out_.path + ": read error");

    std::uint64_t lineNo = 0;
    std::size_t pos = 0;
    std::string joined;  // a statement continued over lines with a trailing backslash
    std::uint64_t statementLine = 0;
    while (pos < text.size()) {
      std::size_t end = text.find('\n', pos);
      if (end == std::string::npos) end = text.size();
      std::string_view line(text.data() + pos, end - pos);
      pos = end + 1;
      ++lineNo;
      if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
      if (joined.empty()) statementLine = lineNo;
      if (!line.empty() && line.back() == '\\') {
        joined.append(line.substr(0, line.size() - 1)).push_back(' ');
        continue;
      }
      if (!joined.empty()) {
        joined.append(line);
        statement(joined, statementLine);
        joined.clear();
      } else {
        statement(line, lineNo);
      }
    }
    if (!joined.empty()) statement(joined, statementLine);

    // Vertices in file order, repeats joined; then faces (positive indices may point forward).
    std::vector<std::uint32_t> id(raw_.size());
    for (std::size_t i = 0; i < raw_.size(); ++i) id[i] = builder_.vertex(raw_[i]);
    for (const Face& f : faces_) {
      std::vector<std::uint32_t> ring;
      ring.reserve(f.count);
      for (std::uint32_t k = 0; k < f.count; ++k) {
        const std::int64_t c = corners_[f.first + k];
        if (c >= static_cast<std::int64_t>(raw_.size())) {
          fail(f.line, "vertex index " + std::to_string(c + 1) + " is out of range: the file has " +
                           std::to_string(raw_.size()) + " vertices");
        }
        ring.push_back(id[static_cast<std::size_t>(c)]);
      }
      builder_.addFace({std::move(ring)}, f.material, f.object, f.line,
                       [&] { return out_.path + ":" + std::to_string(f.line); });
    }
    builder_.finish();
  }

 private:
  struct Face {
    std::uint64_t line;
    std::uint32_t material, object;
    std::size_t first;
    std::uint32_t count;
  };

  [[noreturn]] void fail(std::uint64_t line, const std::string& message) const {
    throw Error(out_.path + ":" + std::to_string(line) + ": " + message);
  }

  double number(std::string_view t, std::uint64_t line) const {
    std::string_view s = t;
    if (s.size() > 1 && s[0] == '+') s.remove_prefix(1);  // from_chars does not take a '+'
    double d = 0;
    const auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), d);
    if (ec != std::errc() || p != s.data() + s.size()) {
      fail(line, "'" + std::string(t) + "' is not a number");
    }
    if (!std::isfinite(d)) fail(line, "'" + std::string(t) + "' is not a finite number");
    return d;
  }

  // One corner "v", "v/vt", "v/vt/vn" or "v//vn": the vertex index, 0-based (may be past the
  // vertices read so far; checked at the end). Texture and normal indices must be integers.
  std::int64_t corner(std::string_view t, std::uint64_t line) const {
    std::int64_t index[3] = {0, 0, 0};
    std::size_t part = 0, start = 0;
    for (std::size_t i = 0; i <= t.size(); ++i) {
      if (i < t.size() && t[i] != '/') continue;
      const std::string_view s = t.substr(start, i - start);
      if (part >= 3) fail(line, "face corner '" + std::string(t) + "' has more than three parts");
      if (!(s.empty() && part > 0)) {
        std::int64_t value = 0;
        const auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), value);
        if (ec != std::errc() || p != s.data() + s.size() || s.empty()) {
          fail(line, "face corner '" + std::string(t) + "': '" + std::string(s) +
                         "' is not an integer index");
        }
        index[part] = value;
      }
      ++part;
      start = i + 1;
    }
    const std::int64_t k = index[0];
    if (k == 0) fail(line, "face corner '" + std::string(t) + "': index 0 (OBJ counts from 1)");
    if (k > 0) return k - 1;
    // Negative: relative to the vertices read so far (-1 is the last one).
    const std::int64_t r = static_cast<std::int64_t>(raw_.size()) + k;
    if (r < 0) {
      fail(line, "vertex index " + std::to_string(k) + " is out of range: only " +
                     std::to_string(raw_.size()) + " vertices so far");
    }
    return r;
  }

  void statement(std::string_view line, std::uint64_t lineNo) {
    if (const std::size_t hash = line.find('#'); hash != std::string_view::npos)
      line = line.substr(0, hash);
    line = trim(line);
    if (line.empty()) return;
    const std::size_t sp = std::min(line.size(), line.find_first_of(" \t"));
    const std::string_view key = line.substr(0, sp);
    const std::string_view rest = trim(line.substr(sp));

    if (key == "v") {
      const auto t = tokens(rest);
      if (t.size() < 3) {
        fail(lineNo,
             "a vertex needs three coordinates x y z, this one has " + std::to_string(t.size()));
      }
      // A w or vertex colour may follow; they must be numbers too but are not used.
      for (std::size_t i = 3; i < t.size(); ++i) number(t[i], lineNo);
      raw_.emplace_back(number(t[0], lineNo), number(t[1], lineNo), number(t[2], lineNo));
    } else if (key == "f" || key == "fo") {
      const auto t = tokens(rest);
      if (t.size() < 3) {
        fail(lineNo,
             "a face needs at least three corners, this one has " + std::to_string(t.size()));
      }
      if (t.size() > std::numeric_limits<std::uint32_t>::max()) fail(lineNo, "face too large");
      // Faces before any usemtl / o / g get the name "", made here so that it exists only when
      // such faces do.
      if (material_ == kUnset) material_ = builder_.material("");
      if (object_ == kUnset) object_ = builder_.object("");
      Face f{lineNo, material_, object_, corners_.size(), static_cast<std::uint32_t>(t.size())};
      for (const auto& c : t) corners_.push_back(corner(c, lineNo));
      faces_.push_back(f);
    } else if (key == "usemtl") {
      material_ = builder_.material(std::string(rest));
    } else if (key == "o" || key == "g") {
      object_ = builder_.object(std::string(rest));
    }
    // Everything else carries no polygon: texture coordinates and normals (vt, vn, vp), points
    // and lines (p, l), smoothing groups, material libraries, free-form curve statements, and
    // exporters' own extensions. They are skipped, as other readers do.
  }

  MeshFile& out_;
  Builder builder_;
  std::vector<Eigen::Vector3d> raw_;
  std::vector<Face> faces_;
  std::vector<std::int64_t> corners_;
  std::uint32_t material_ = kUnset, object_ = kUnset;
  static constexpr std::uint32_t kUnset = 0xffffffffu;
};

// ---------------------------------------------------------------------------------------------
// Assimp.

std::string assimpError(const std::string& path, const Assimp::Importer& importer) {
  const char* m = importer.GetErrorString();
  return path + ": Assimp cannot read it" + ((m && *m) ? std::string(": ") + m : std::string());
}

void readAssimp(MeshFile& out, const MeshFileOptions& options, const std::string& ext) {
  Assimp::Importer importer;
  // No triangulation (Mesh takes convex polygons, and Builder cuts the others), no other
  // clean-up: Builder joins vertices by exact position across meshes, which JoinIdenticalVertices
  // (per mesh, and only when normals and texture coordinates agree too) cannot do alone.
  const aiScene* scene = importer.ReadFile(
      out.path, aiProcess_JoinIdenticalVertices | aiProcess_ValidateDataStructure);
  if (!scene) throw Error(assimpError(out.path, importer));
  if (scene->mFlags & AI_SCENE_FLAGS_INCOMPLETE || !scene->mRootNode) {
    throw Error(out.path + ": Assimp read an incomplete scene (no geometry)");
  }
  out.format = "assimp:" + ext;
  out.singlePrecision = kAssimpSinglePrecision;
  Builder builder(out, options);

  std::function<void(const aiNode*, const Eigen::Matrix4d&)> walk =
      [&](const aiNode* node, const Eigen::Matrix4d& parent) {
        const aiMatrix4x4& t = node->mTransformation;
        Eigen::Matrix4d local;
        local << t.a1, t.a2, t.a3, t.a4, t.b1, t.b2, t.b3, t.b4, t.c1, t.c2, t.c3, t.c4, t.d1, t.d2,
            t.d3, t.d4;
        const Eigen::Matrix4d world = parent * local;
        for (unsigned k = 0; k < node->mNumMeshes; ++k) {
          const aiMesh* mesh = scene->mMeshes[node->mMeshes[k]];
          std::string materialName;
          if (mesh->mMaterialIndex < scene->mNumMaterials) {
            aiString name;
            if (scene->mMaterials[mesh->mMaterialIndex]->Get(AI_MATKEY_NAME, name) == AI_SUCCESS) {
              materialName = name.C_Str();
            }
          }
          const std::string objectName =
              node->mName.length ? node->mName.C_Str() : mesh->mName.C_Str();
          const std::uint32_t material = builder.material(materialName);
          const std::uint32_t object = builder.object(objectName);
          std::vector<std::uint32_t> id(mesh->mNumVertices);
          for (unsigned i = 0; i < mesh->mNumVertices; ++i) {
            const aiVector3D& q = mesh->mVertices[i];
            const Eigen::Vector3d p = world.topLeftCorner<3, 3>() * Eigen::Vector3d(q.x, q.y, q.z) +
                                      world.topRightCorner<3, 1>();
            if (!p.allFinite()) {
              throw Error(out.path + ": mesh '" + mesh->mName.C_Str() + "' vertex " +
                          std::to_string(i) + " has a non-finite coordinate");
            }
            id[i] = builder.vertex(p);
          }
          for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
            const aiFace& face = mesh->mFaces[f];
            if (face.mNumIndices < 3) continue;  // points and lines carry no surface
            std::vector<std::uint32_t> ring(face.mNumIndices);
            for (unsigned c = 0; c < face.mNumIndices; ++c) ring[c] = id[face.mIndices[c]];
            builder.addFace({std::move(ring)}, material, object, f, [&] {
              return out.path + ": mesh '" + mesh->mName.C_Str() + "' face " + std::to_string(f);
            });
          }
        }
        for (unsigned c = 0; c < node->mNumChildren; ++c) walk(node->mChildren[c], world);
      };
  walk(scene->mRootNode, Eigen::Matrix4d::Identity());
  builder.finish();
}

// ---------------------------------------------------------------------------------------------
// GDAL/OGR.

using detail::QuietGdalErrors;
using detail::gdalMessage;

// Layer geometry types that can hold surfaces (the others are skipped when no layer is named).
bool surfaceLayer(OGRwkbGeometryType type) {
  const OGRwkbGeometryType t = wkbFlatten(type);
  return t == wkbUnknown || t == wkbGeometryCollection || OGR_GT_IsSurface(t) ||
         OGR_GT_IsSubClassOf(t, wkbMultiSurface) || OGR_GT_IsSubClassOf(t, wkbPolyhedralSurface);
}

class OgrReader {
 public:
  OgrReader(MeshFile& out, const MeshFileOptions& options)
      : out_(out), options_(options), builder_(out, options) {}

  void read(GDALDataset& ds) {
    out_.format = std::string("ogr:") + (ds.GetDriver() ? ds.GetDriver()->GetDescription() : "");
    std::vector<OGRLayer*> layers;
    if (!options_.layer.empty()) {
      OGRLayer* layer = ds.GetLayerByName(options_.layer.c_str());
      if (!layer) {
        std::string names;
        for (OGRLayer* l : ds.GetLayers())
          names += (names.empty() ? "" : ", ") + std::string(l->GetName());
        throw Error(out_.path + ": no layer '" + options_.layer + "' (layers: " + names + ")");
      }
      layers.push_back(layer);
    } else {
      for (OGRLayer* l : ds.GetLayers()) {
        if (surfaceLayer(l->GetGeomType())) layers.push_back(l);
      }
    }
    const OGRSpatialReference* crs = nullptr;
    for (OGRLayer* layer : layers) {
      if (const OGRSpatialReference* srs = layer->GetSpatialRef()) {
        if (!crs) {
          crs = srs;
          char* wkt = nullptr;
          if (srs->exportToWkt(&wkt) == OGRERR_NONE && wkt) out_.crsWkt = wkt;
          CPLFree(wkt);
        } else if (!crs->IsSame(srs)) {
          // One mesh has one frame: mixing CRSs would put polygons at meaningless places.
          throw Error(out_.path + ": layer '" + layer->GetName() +
                      "' has a different CRS from the layers before it; name one layer");
        }
      }
      readLayer(*layer);
    }
    builder_.finish();
  }

 private:
  void readLayer(OGRLayer& layer) {
    const std::string name = layer.GetName();
    int field = -1;
    if (!options_.materialField.empty()) {
      field = layer.GetLayerDefn()->GetFieldIndex(options_.materialField.c_str());
      if (field < 0) {
        std::string fields;
        for (int i = 0; i < layer.GetLayerDefn()->GetFieldCount(); ++i) {
          fields +=
              (i ? ", " : "") + std::string(layer.GetLayerDefn()->GetFieldDefn(i)->GetNameRef());
        }
        throw Error(out_.path + ": layer '" + name + "' has no field '" + options_.materialField +
                    "' (fields: " + fields + ")");
      }
    }
    const std::uint32_t layerMaterial = field < 0 ? builder_.material(name) : 0;
    layer.ResetReading();
    std::uint64_t sequence = 0;
    for (auto& feature : layer) {
      const GIntBig fid = feature->GetFID();
      const std::uint64_t id = fid == OGRNullFID ? sequence : static_cast<std::uint64_t>(fid);
      ++sequence;
      const OGRGeometry* g = feature->GetGeometryRef();
      if (!g || g->IsEmpty()) continue;
      const auto where = [&] {
        return out_.path + ": layer '" + name + "' feature " + std::to_string(id);
      };
      if (!g->Is3D()) {
        throw Error(where() + ": " + OGRGeometryTypeToName(g->getGeometryType()) +
                    " has no Z coordinates; a terrain needs heights");
      }
      std::uint32_t material = layerMaterial;
      if (field >= 0) {
        material = builder_.material(
            feature->IsFieldSetAndNotNull(field) ? feature->GetFieldAsString(field) : "");
      }
      const std::uint32_t object = builder_.object(name + ":" + std::to_string(id));
      addGeometry(*g, material, object, id, where);
    }
  }

  void addGeometry(const OGRGeometry& g, std::uint32_t material, std::uint32_t object,
                   std::uint64_t id, const Builder::Where& where) {
    switch (wkbFlatten(g.getGeometryType())) {
      case wkbPolygon:
      case wkbTriangle:
        addPolygon(*g.toPolygon(), material, object, id, where);
        return;
      case wkbCurvePolygon: {
        // Arcs become line segments, as GDAL's default stroking does.
        std::unique_ptr<OGRGeometry> linear(g.getLinearGeometry());
        if (linear) addGeometry(*linear, material, object, id, where);
        return;
      }
      case wkbMultiPolygon:
      case wkbMultiSurface:
      case wkbGeometryCollection:
        for (const OGRGeometry* part : *g.toGeometryCollection())
          addGeometry(*part, material, object, id, where);
        return;
      case wkbPolyhedralSurface:
      case wkbTIN: {
        // Each patch is a polygon; patches share corners, which Builder joins into shared vertices.
        const OGRPolyhedralSurface* s = g.toPolyhedralSurface();
        for (int i = 0; i < s->getNumGeometries(); ++i)
          addPolygon(*s->getGeometryRef(i), material, object, id, where);
        return;
      }
      default:
        throw Error(where() + ": " + OGRGeometryTypeToName(g.getGeometryType()) +
                    " is not a surface; only polygons, TINs and polyhedral surfaces make terrain");
    }
  }

  void addPolygon(const OGRPolygon& polygon, std::uint32_t material, std::uint32_t object,
                  std::uint64_t id, const Builder::Where& where) {
    std::vector<std::vector<std::uint32_t>> rings;
    for (const OGRLinearRing* ring : polygon) {
      std::vector<std::uint32_t> r;
      r.reserve(static_cast<std::size_t>(ring->getNumPoints()));
      for (int i = 0; i < ring->getNumPoints(); ++i) {
        const Eigen::Vector3d p(ring->getX(i), ring->getY(i), ring->getZ(i));
        if (!p.allFinite()) throw Error(where() + ": a non-finite coordinate");
        r.push_back(builder_.vertex(p));
      }
      rings.push_back(std::move(r));
    }
    if (rings.empty()) return;
    builder_.addFace(std::move(rings), material, object, id, where);
  }

  MeshFile& out_;
  const MeshFileOptions& options_;
  Builder builder_;
};

std::string lowerExtension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  if (!ext.empty()) ext.erase(0, 1);
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}

// Names GDAL opens that are not files: /vsi paths and connection strings ("PG:...").
bool gdalOnlyName(const std::string& path) {
  if (path.rfind("/vsi", 0) == 0) return true;
  const std::size_t colon = path.find(':');
  return colon != std::string::npos && colon > 1 && path.find('/') > colon;
}

}  // namespace

std::int64_t MeshFile::materialIndex(std::string_view name) const {
  const auto it = std::find(materials.begin(), materials.end(), name);
  return it == materials.end() ? -1 : it - materials.begin();
}

std::int64_t MeshFile::objectIndex(std::string_view name) const {
  const auto it = std::find(objects.begin(), objects.end(), name);
  return it == objects.end() ? -1 : it - objects.begin();
}

// Assimp and OGR, kept at arm's length. Their parsers are not ours to fix, and hostile files make
// some of them loop for ever or crash: a PLY header with a mangled end_header sends Debian's
// Assimp 5.2 seeking without end, a 157-byte DXF file sends GDAL 3.6's DXF driver round for ever.
// So those reads run in a child process: the child reads the file and sends the mesh back
// through a pipe; the parent waits at most MeshFileOptions::readerSeconds (plus a second per 5 MB
// of file) and turns a crash, a hang or a garbled reply into a qota::Error naming the file.
namespace isolated {

class Pipe {
 public:
  explicit Pipe(int fd) : fd_(fd) {}
  bool write(const void* p, std::size_t n) {
    const char* c = static_cast<const char*>(p);
    while (n > 0) {
      const ssize_t k = ::write(fd_, c, n);
      if (k < 0 && errno == EINTR) continue;
      if (k <= 0) return false;
      c += k, n -= static_cast<std::size_t>(k);
    }
    return true;
  }
  template <class T>
  bool pod(const T& v) { return write(&v, sizeof v); }
  template <class T>
  bool vec(const std::vector<T>& v) { return pod<std::uint64_t>(v.size()) && write(v.data(), v.size() * sizeof(T)); }
  bool str(const std::string& s) { return pod<std::uint64_t>(s.size()) && write(s.data(), s.size()); }

 private:
  int fd_;
};

// Reads the child's reply with a deadline; false on timeout, error or end of data.
class Reply {
 public:
  Reply(int fd, std::chrono::steady_clock::time_point deadline) : fd_(fd), deadline_(deadline) {}
  bool read(void* p, std::size_t n) {
    char* c = static_cast<char*>(p);
    while (n > 0) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline_ - std::chrono::steady_clock::now());
      if (left.count() <= 0) return timedOut_ = true, false;
      pollfd pfd{fd_, POLLIN, 0};
      const int r = ::poll(&pfd, 1, static_cast<int>(std::min<long long>(left.count(), 1000)));
      if (r < 0 && errno == EINTR) continue;
      if (r < 0) return false;
      if (r == 0) continue;
      const ssize_t k = ::read(fd_, c, n);
      if (k < 0 && errno == EINTR) continue;
      if (k <= 0) return false;
      c += k, n -= static_cast<std::size_t>(k);
    }
    return true;
  }
  template <class T>
  bool pod(T& v) { return read(&v, sizeof v); }
  // A vector of at most `limit` elements (a garbled count must not allocate the machine away).
  template <class T>
  bool vec(std::vector<T>& v, std::uint64_t limit) {
    std::uint64_t n = 0;
    if (!pod(n) || n > limit) return false;
    v.resize(n);
    return read(v.data(), n * sizeof(T));
  }
  bool str(std::string& s) {
    std::uint64_t n = 0;
    if (!pod(n) || n > (1u << 24)) return false;
    s.resize(n);
    return read(s.data(), n);
  }
  bool timedOut() const { return timedOut_; }

 private:
  int fd_;
  std::chrono::steady_clock::time_point deadline_;
  bool timedOut_ = false;
};

bool send(Pipe& p, const MeshFile& m) {
  bool ok = p.pod<char>('M') && p.str(m.format) && p.str(m.crsWkt) && p.pod<std::uint8_t>(m.singlePrecision) && p.pod(m.origin) &&
            p.pod<std::uint64_t>(m.degenerate) && p.pod<std::uint64_t>(m.triangulated) &&
            p.vec(m.mesh.vertices) && p.vec(m.mesh.indices) && p.vec(m.mesh.offsets) &&
            p.vec(m.polygonMaterial) && p.vec(m.polygonObject) && p.vec(m.polygonSource) &&
            p.pod<std::uint64_t>(m.materials.size());
  for (const auto& s : m.materials) ok = ok && p.str(s);
  ok = ok && p.pod<std::uint64_t>(m.objects.size());
  for (const auto& s : m.objects) ok = ok && p.str(s);
  return ok;
}

bool receive(Reply& r, MeshFile& m) {
  constexpr std::uint64_t kLimit = 1ull << 32;
  std::uint8_t single = 0;
  std::uint64_t materials = 0, objects = 0;
  bool ok = r.str(m.format) && r.str(m.crsWkt) && r.pod(single) && r.pod(m.origin) && r.pod(m.degenerate) && r.pod(m.triangulated) &&
            r.vec(m.mesh.vertices, kLimit) && r.vec(m.mesh.indices, kLimit) && r.vec(m.mesh.offsets, kLimit) &&
            r.vec(m.polygonMaterial, kLimit) && r.vec(m.polygonObject, kLimit) && r.vec(m.polygonSource, kLimit) &&
            r.pod(materials) && materials <= kLimit;
  for (std::uint64_t i = 0; ok && i < materials; ++i) ok = r.str(m.materials.emplace_back());
  ok = ok && r.pod(objects) && objects <= kLimit;
  for (std::uint64_t i = 0; ok && i < objects; ++i) ok = r.str(m.objects.emplace_back());
  m.singlePrecision = single != 0;
  return ok;
}

}  // namespace isolated

// Runs read(out) in a child process and takes its MeshFile back (see above); `reader` names the
// library in messages.
void readIsolated(MeshFile& out, const MeshFileOptions& options, const char* reader,
                  const std::function<void(MeshFile&)>& read) {
  int fds[2];
  if (::pipe(fds) != 0) throw Error(out.path + ": cannot start the mesh reader (pipe)");
  const pid_t pid = ::fork();
  if (pid < 0) {
    ::close(fds[0]), ::close(fds[1]);
    throw Error(out.path + ": cannot start the mesh reader (fork)");
  }
  if (pid == 0) {  // the child: read, send, leave without running the parent's exit handlers
    ::close(fds[0]);
    isolated::Pipe pipe(fds[1]);
    try {
      read(out);
      isolated::send(pipe, out);
    } catch (const std::exception& e) {
      pipe.pod<char>('E') && pipe.str(e.what());
    }
    ::close(fds[1]);
    ::_exit(0);
  }
  ::close(fds[1]);
  std::error_code ec;
  const auto bytes = std::filesystem::file_size(out.path, ec);
  const double seconds = options.readerSeconds + static_cast<double>(ec ? 0 : bytes) / 5e6;
  isolated::Reply reply(fds[0], std::chrono::steady_clock::now() +
                                    std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                        std::chrono::duration<double>(seconds)));
  char kind = 0;
  std::string message;
  bool ok = reply.pod(kind) && (kind == 'M' ? isolated::receive(reply, out) : kind == 'E' && reply.str(message));
  const bool timedOut = reply.timedOut();
  ::close(fds[0]);
  if (timedOut || !ok) ::kill(pid, SIGKILL);
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (timedOut) {
    throw Error(out.path + ": " + reader + " took more than " + std::to_string(static_cast<long>(seconds)) +
                " s to read it; giving up");
  }
  if (WIFSIGNALED(status) && !ok) {
    throw Error(out.path + ": " + reader + " crashed reading it (signal " + std::to_string(WTERMSIG(status)) + ")");
  }
  if (!ok) throw Error(out.path + ": " + reader + "'s reply was cut short");
  if (kind == 'E') throw Error(message);
}

MeshFile loadMeshFile(const std::string& path, const MeshFileOptions& options) {
  MeshFile out;
  out.path = path;
  std::error_code ec;
  const bool exists = std::filesystem::exists(path, ec);
  if (!exists && !gdalOnlyName(path)) throw Error(path + ": no such file");
  const std::string ext = lowerExtension(path);

  if (ext == "obj") {
    out.format = "obj";
    ObjReader reader(out, options);
    reader.read();
    return out;
  }

  ensureGdalRegistered();
  {
    QuietGdalErrors quiet;
    // A file a GDAL vector driver recognises goes to OGR first: doubles, and the CRS.
    const bool gdalKnows =
        !exists || GDALIdentifyDriverEx(path.c_str(), GDAL_OF_VECTOR, nullptr, nullptr);
    if (gdalKnows) {
      readIsolated(out, options, "GDAL/OGR", [&](MeshFile& m) {
        const QuietGdalErrors quietChild;
        std::unique_ptr<GDALDataset> ds(GDALDataset::Open(
            path.c_str(), GDAL_OF_VECTOR | GDAL_OF_READONLY | GDAL_OF_VERBOSE_ERROR));
        if (!ds) throw Error(path + ": cannot open as a vector dataset" + gdalMessage());
        OgrReader reader(m, options);
        reader.read(*ds);
      });
      return out;
    }
  }
  Assimp::Importer importer;
  if (!ext.empty() && importer.IsExtensionSupported(ext)) {
    readIsolated(out, options, "Assimp", [&](MeshFile& m) { readAssimp(m, options, ext); });
    return out;
  }
  throw Error(path +
              ": unknown format: not OBJ, not a mesh format Assimp reads (by extension), "
              "not a vector dataset GDAL recognises");
}

}  // namespace qota
