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
  if (triangleCount == 0 || vertexCount >= kNone) return false;
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

  // Each edge once, or twice in opposite directions; those used once form the boundary, a
  // successor a vertex (next).
  std::vector<std::uint32_t> next(used, kNone);
  std::size_t boundary = 0;
  std::uint32_t start = kNone;
  for (std::uint32_t a = 0; a < used; ++a) {
    for (std::uint32_t i = first[a]; i < first[a + 1]; ++i) {
      const std::uint32_t b = to[i];
      for (std::uint32_t j = first[a]; j < i; ++j) {
        if (to[j] == b) return false;  // a -> b twice
      }
      bool back = false;
      for (std::uint32_t j = first[b]; j < first[b + 1] && !back; ++j) back = to[j] == a;
      if (back) continue;
      if (next[a] != kNone) return false;  // two boundary edges leave a
      next[a] = b;
      ++boundary;
      // The loop's start: its least vertex by (u, v), a corner of the polygon where it turns
      // the way the polygon winds.
      const Point2 pa = point(a);
      if (start == kNone || pa.u < point(start).u || (pa.u == point(start).u && pa.v < point(start).v)) start = a;
    }
  }
  if (boundary < 3) return false;

  // One loop through every boundary edge.
  std::vector<std::uint32_t> loop;
  loop.reserve(boundary);
  for (std::uint32_t v = start; loop.size() <= boundary;) {
    loop.push_back(v);
    v = next[v];
    if (v == kNone) return false;
    if (v == start) break;
  }
  if (loop.size() != boundary) return false;

  // Counter-clockwise: the turn at the least vertex (a convex corner of a simple polygon).
  const std::size_t m = loop.size();
  const auto at = [&](std::size_t i) { return point(loop[i % m]); };
  if (orient2dSign(at(m - 1), at(0), at(1)) <= 0) return false;

  // Simple: no two edges meet but neighbours at their shared corner (and those do not fold back
  // along each other). Edges are bucketed on a grid over their boxes; a pair that meets shares a
  // cell, as both boxes hold the meeting point and the cells are a monotonic function of it.
  double ulo = INFINITY, uhi = -INFINITY, vlo = INFINITY, vhi = -INFINITY;
  for (std::uint32_t v : loop) {
    const Point2 p = point(v);
    ulo = std::min(ulo, p.u), uhi = std::max(uhi, p.u), vlo = std::min(vlo, p.v), vhi = std::max(vhi, p.v);
  }
  const auto side = static_cast<std::uint32_t>(std::clamp(std::sqrt(static_cast<double>(m)), 1.0, 1024.0));
  const double su = uhi > ulo ? side / (uhi - ulo) : 0, sv = vhi > vlo ? side / (vhi - vlo) : 0;
  const auto cell = [side](double x, double lo, double scale) {
    return static_cast<std::uint32_t>(std::clamp(std::floor((x - lo) * scale), 0.0, side - 1.0));
  };
  std::vector<std::vector<std::uint32_t>> cells(static_cast<std::size_t>(side) * side);
  for (std::size_t e = 0; e < m; ++e) {
    const Point2 p = at(e), q = at(e + 1);
    const std::uint32_t c0 = cell(std::min(p.u, q.u), ulo, su), c1 = cell(std::max(p.u, q.u), ulo, su);
    const std::uint32_t r0 = cell(std::min(p.v, q.v), vlo, sv), r1 = cell(std::max(p.v, q.v), vlo, sv);
    for (std::uint32_t r = r0; r <= r1; ++r) {
      for (std::uint32_t c = c0; c <= c1; ++c) cells[static_cast<std::size_t>(r) * side + c].push_back(e);
    }
  }
  // (A boundary crowded into a few cells would cost its square: past a budget the pairs decide.)
  std::size_t budget = 64 * m + (1u << 20);
  for (const auto& in : cells) {
    for (std::size_t x = 0; x < in.size(); ++x) {
      for (std::size_t y = x + 1; y < in.size(); ++y) {
        if (budget-- == 0) return false;
        std::size_t e = in[x], f = in[y];
        if (f < e) std::swap(e, f);
        const Point2 p = at(e), q = at(e + 1), r = at(f), s = at(f + 1);
        if (f == e + 1 || (e == 0 && f == m - 1)) {
          // Neighbours: shared corner q (or p, for the last and the first), the other two ends
          // must not lie along one line on the same side of it.
          const Point2 shared = f == e + 1 ? q : p, a = f == e + 1 ? p : q, b = f == e + 1 ? s : r;
          if (m == 3) continue;  // (a triangle: its corners are not collinear, seen above)
          if (orient2dSign(a, shared, b) != 0) continue;
          const bool backU = (a.u - shared.u > 0) == (b.u - shared.u > 0) && a.u != shared.u && b.u != shared.u;
          const bool backV = (a.v - shared.v > 0) == (b.v - shared.v > 0) && a.v != shared.v && b.v != shared.v;
          if (backU || backV) return false;
          continue;
        }
        if (segmentsMeet(p, q, r, s)) return false;
      }
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
