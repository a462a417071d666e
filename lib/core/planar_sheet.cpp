// The one-sheet proof (planar_sheet.hpp): vertex numbers, then the boundary loop, then its
// simplicity by exact orientations.
#include "planar_sheet.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "qota/predicates.hpp"
#include "qota/terrain.hpp"

namespace qota {

namespace {

constexpr std::uint32_t kNone = 0xffffffffu;

// Whether the closed segments pq and rs meet (exact orientations; collinear ones by their extents).
bool segmentsMeet(Point2 p, Point2 q, Point2 r, Point2 s) {
  const int a = orient2dSign(p, q, r), b = orient2dSign(p, q, s);
  const int c = orient2dSign(r, s, p), d = orient2dSign(r, s, q);
  if (a * b > 0 || c * d > 0) return false;
  if (a != 0 || b != 0 || c != 0 || d != 0) return true;
  // All four on one line: they meet where their extents along it overlap (both axes, so a
  // vertical line is compared by v).
  const auto overlap = [](double a0, double a1, double b0, double b1) {
    return std::max(std::min(a0, a1), std::min(b0, b1)) <= std::min(std::max(a0, a1), std::max(b0, b1));
  };
  return overlap(p.u, q.u, r.u, s.u) && overlap(p.v, q.v, r.v, s.v);
}

}  // namespace

bool detail::oneSheet(std::span<const TriangleCorners> triangles, std::span<const Point2> vertices,
                      std::span<const std::uint8_t> left) {
  const std::size_t vertexCount = vertices.size(), triangleCount = triangles.size();
  if (triangleCount == 0 || vertexCount >= kNone || triangleCount >= kNone / 3) return false;  // (32-bit counts)
  const auto live = [&](std::size_t t) { return left.empty() || !left[t]; };

  // The vertices renumbered in the order the triangles (in Morton order) first use them, so that
  // the edge lists below are read near where they were written: a vertex's neighbours are then
  // mostly in cache, where the mesh's own numbering (a TIN's points in any order) sends nearly
  // every lookup to memory.
  std::vector<std::uint32_t> rank(vertexCount, kNone), vertexOf;
  vertexOf.reserve(vertexCount);
  for (std::size_t t = 0; t < triangleCount; ++t) {
    if (!live(t)) continue;
    for (std::uint32_t c : triangles[t].corner) {
      if (rank[c] == kNone) rank[c] = static_cast<std::uint32_t>(vertexOf.size()), vertexOf.push_back(c);
    }
  }
  const auto used = static_cast<std::uint32_t>(vertexOf.size());
  // The directed edges by their first vertex (counting sort): first[a]..first[a + 1] in `to`.
  std::vector<std::uint32_t> first(used + 1, 0);
  for (std::size_t t = 0; t < triangleCount; ++t) {
    if (!live(t)) continue;
    for (std::uint32_t a : triangles[t].corner) ++first[rank[a] + 1];
  }
  for (std::uint32_t a = 0; a < used; ++a) first[a + 1] += first[a];
  std::vector<std::uint32_t> to(first[used]), fill(first.begin(), first.end() - 1);
  for (std::size_t t = 0; t < triangleCount; ++t) {
    if (!live(t)) continue;
    const auto& c = triangles[t].corner;
    for (int k = 0; k < 3; ++k) to[fill[rank[c[k]]]++] = rank[c[k == 2 ? 0 : k + 1]];
  }
  std::vector<std::uint32_t>().swap(fill);
  std::vector<std::uint32_t>().swap(rank);
  const auto point = [&](std::uint32_t a) { return vertices[vertexOf[a]]; };

  // Each edge once, or twice in opposite directions; those used once form the boundary: each
  // boundary vertex left by one boundary edge and entered by one (next: its successor).
  std::vector<std::uint32_t> next(used, kNone), edges;  // edges: each boundary edge by its first vertex
  std::vector<std::uint8_t> entered(used, 0);
  for (std::uint32_t a = 0; a < used; ++a) {
    for (std::uint32_t i = first[a]; i < first[a + 1]; ++i) {
      const std::uint32_t b = to[i];
      for (std::uint32_t j = first[a]; j < i; ++j) {
        if (to[j] == b) return false;  // a -> b twice
      }
      bool back = false;
      for (std::uint32_t j = first[b]; j < first[b + 1] && !back; ++j) back = to[j] == a;
      if (back) continue;
      if (next[a] != kNone || entered[b]) return false;  // two boundary edges leave a, or enter b
      next[a] = b, entered[b] = 1;
      edges.push_back(a);
    }
  }
  std::vector<std::uint32_t>().swap(to);
  std::vector<std::uint32_t>().swap(first);
  const std::size_t m = edges.size();
  if (m < 3) return false;

  // The loops. A boundary vertex is left once and entered once, so the boundary edges fall into
  // loops that share no vertex. Each loop's turn at its least vertex by (u, v) (a convex corner
  // of a simple polygon) says which way it winds: +1 counter-clockwise, -1 clockwise.
  std::vector<std::uint32_t> loopOf(used, kNone);
  struct Loop {
    std::uint32_t least;
    int winds;
  };
  std::vector<Loop> loops;
  const auto before = [&](Point2 p, Point2 q) { return p.u < q.u || (p.u == q.u && p.v < q.v); };
  for (const std::uint32_t start : edges) {
    if (loopOf[start] != kNone) continue;
    const auto id = static_cast<std::uint32_t>(loops.size());
    std::uint32_t least = start, previous = kNone, beforeLeast = kNone;
    for (std::uint32_t v = start;;) {
      if (next[v] == kNone) return false;  // entered, never left
      loopOf[v] = id;
      if (before(point(v), point(least))) least = v, beforeLeast = previous;
      previous = v;
      v = next[v];
      if (v == start) break;
    }
    if (beforeLeast == kNone) beforeLeast = previous;  // (the least is the start: the last vertex)
    const int turn = orient2dSign(point(beforeLeast), point(least), point(next[least]));
    if (turn == 0) return false;
    loops.push_back({least, turn});
  }

  // Simple and apart: no two boundary edges meet but neighbours at their shared corner (which
  // must not fold back along each other). Edges are bucketed on a grid over their boxes; a pair
  // that meets shares a cell, as both boxes hold the meeting point and the cells are a monotonic
  // function of it. (A boundary crowded into a few cells would cost its square: past a budget
  // the pairs decide.)
  double ulo = INFINITY, uhi = -INFINITY, vlo = INFINITY, vhi = -INFINITY;
  for (const std::uint32_t a : edges) {
    const Point2 p = point(a);
    ulo = std::min(ulo, p.u), uhi = std::max(uhi, p.u), vlo = std::min(vlo, p.v), vhi = std::max(vhi, p.v);
  }
  const auto side = static_cast<std::uint32_t>(std::clamp(std::sqrt(static_cast<double>(m)), 1.0, 1024.0));
  const double su = uhi > ulo ? side / (uhi - ulo) : 0, sv = vhi > vlo ? side / (vhi - vlo) : 0;
  const auto cell = [side](double x, double lo, double scale) {
    return static_cast<std::uint32_t>(std::clamp(std::floor((x - lo) * scale), 0.0, side - 1.0));
  };
  std::vector<std::vector<std::uint32_t>> cells(static_cast<std::size_t>(side) * side);
  for (const std::uint32_t a : edges) {
    const Point2 p = point(a), q = point(next[a]);
    const std::uint32_t c0 = cell(std::min(p.u, q.u), ulo, su), c1 = cell(std::max(p.u, q.u), ulo, su);
    const std::uint32_t r0 = cell(std::min(p.v, q.v), vlo, sv), r1 = cell(std::max(p.v, q.v), vlo, sv);
    for (std::uint32_t r = r0; r <= r1; ++r) {
      for (std::uint32_t c = c0; c <= c1; ++c) cells[static_cast<std::size_t>(r) * side + c].push_back(a);
    }
  }
  std::size_t budget = 64 * m + (1u << 20);
  for (const auto& in : cells) {
    for (std::size_t x = 0; x < in.size(); ++x) {
      for (std::size_t y = x + 1; y < in.size(); ++y) {
        if (budget-- == 0) return false;
        std::uint32_t e = in[x], f = in[y];
        if (next[f] == e) std::swap(e, f);  // (neighbours: e's end is f's start)
        const Point2 p = point(e), q = point(next[e]), r = point(f), t = point(next[f]);
        if (next[e] == f) {
          // Shared corner q: p and t must not lie along one line on the same side of it.
          if (orient2dSign(p, q, t) != 0) continue;
          const bool backU = (p.u - q.u > 0) == (t.u - q.u > 0) && p.u != q.u && t.u != q.u;
          const bool backV = (p.v - q.v > 0) == (t.v - q.v > 0) && p.v != q.v && t.v != q.v;
          if (backU || backV) return false;
          continue;
        }
        if (segmentsMeet(p, q, r, t)) return false;
      }
    }
  }

  if (loops.size() == 1) return loops[0].winds > 0;
  // Nested right: inside a counter-clockwise loop the count must be 1, so the loops round it
  // must wind 0 in all (a hole's clockwise loop round an island's, an outer loop round the
  // hole). A loop's least vertex lies off every other loop (they do not meet), so its winding
  // number about each is exact: the crossings of the ray from it towards +u, counted by side
  // (upward edges with it on their left +1, downward ones with it on their right -1), among the
  // edges in the cells the ray passes.
  {
    std::vector<std::uint32_t> seen(used, kNone);  // (an edge in several cells counted once a ray)
    for (std::uint32_t id = 0; id < loops.size(); ++id) {
      if (loops[id].winds < 0) continue;
      const Point2 p = point(loops[id].least);
      const std::uint32_t row = cell(p.v, vlo, sv);
      int around = 0;
      for (std::uint32_t c = cell(p.u, ulo, su); c < side; ++c) {
        for (const std::uint32_t a : cells[static_cast<std::size_t>(row) * side + c]) {
          if (budget-- == 0) return false;
          if (loopOf[a] == id || seen[a] == id) continue;
          seen[a] = id;
          const Point2 q = point(a), r = point(next[a]);
          if (q.v <= p.v && r.v > p.v && orient2dSign(q, r, p) > 0) ++around;
          if (r.v <= p.v && q.v > p.v && orient2dSign(q, r, p) < 0) --around;
        }
      }
      if (around > 0) return false;
    }
  }
  return true;
}

bool PlanarCore::oneSheet() const {
  // (The removed polygons' triangles are left out, as the tree leaves them out.)
  std::vector<std::uint8_t> left;
  if (ledger_.anyRemoved()) {
    left.resize(cold_.size());
    for (std::size_t t = 0; t < cold_.size(); ++t) left[t] = ledger_.removed(cold_[t].polygon);
  }
  return detail::oneSheet(cold_, corners2_, left);
}

}  // namespace qota
