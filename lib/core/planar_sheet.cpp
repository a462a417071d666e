// The one-sheet proof (planar_sheet.hpp): vertex numbers, then the boundary loop, then its
// simplicity by exact orientations.
#include "planar_sheet.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <span>
#include <vector>

#include "qota/predicates.hpp"
#include "qota/terrain.hpp"

namespace qota {

namespace {

constexpr std::uint32_t kNone = 0xffffffffu;

}  // namespace

bool detail::oneSheet(std::span<const TriangleCorners> triangles, std::span<const Point2> vertices,
                      std::span<const std::uint8_t> left) {
  const std::size_t vertexCount = vertices.size(), triangleCount = triangles.size();
  if (triangleCount == 0 || vertexCount >= kNone || triangleCount >= kNone / 3) return false;  // (32-bit counts)
  if (!left.empty() && left.size() != triangleCount) return false;
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
      if (c >= vertexCount) return false;
      if (rank[c] == kNone) rank[c] = static_cast<std::uint32_t>(vertexOf.size()), vertexOf.push_back(c);
    }
  }
  const auto used = static_cast<std::uint32_t>(vertexOf.size());
  // The orientations below are exact for coordinates of magnitude 1e-150 to 1e150 (or 0) only.
  for (const std::uint32_t c : vertexOf) {
    for (const double x : {vertices[c].u, vertices[c].v}) {
      if (!(std::fabs(x) <= 1e150) || (x != 0 && std::fabs(x) < 1e-150)) return false;
    }
  }
  // The directed edges by their first vertex (counting sort): their ends first[a]..first[a + 1] in
  // `next`.
  std::vector<std::uint32_t> first(used + 1, 0);
  for (std::size_t t = 0; t < triangleCount; ++t) {
    if (!live(t)) continue;
    for (std::uint32_t a : triangles[t].corner) ++first[rank[a] + 1];
  }
  for (std::uint32_t a = 0; a < used; ++a) first[a + 1] += first[a];
  std::vector<std::uint32_t> next(first[used]), fill(first.begin(), first.end() - 1);
  for (std::size_t t = 0; t < triangleCount; ++t) {
    if (!live(t)) continue;
    const auto& c = triangles[t].corner;
    for (int k = 0; k < 3; ++k) next[fill[rank[c[k]]]++] = rank[c[k == 2 ? 0 : k + 1]];
  }
  std::vector<std::uint32_t>().swap(fill);
  std::vector<std::uint32_t>().swap(rank);
  // Each vertex's ends sorted: a repeated edge is then two equal neighbours, and an edge's
  // reverse a binary search (a fan of many triangles round one vertex costs its log, not its
  // square).
  for (std::uint32_t a = 0; a < used; ++a) std::sort(next.begin() + first[a], next.begin() + first[a + 1]);
  const auto point = [&](std::uint32_t a) { return vertices[vertexOf[a]]; };

  // Each edge once, or twice in opposite directions; those used once form the boundary, each
  // boundary vertex left by as many boundary edges as enter it (one, or more where the sheet
  // pinches: two voids meeting at a corner).
  std::vector<std::uint32_t> from, to;  // the boundary edges
  std::vector<std::uint32_t> outOf(used, kNone);
  std::vector<std::uint8_t> outs(used, 0), ins(used, 0);
  constexpr std::uint8_t kMostAtAPinch = 8;
  for (std::uint32_t a = 0; a < used; ++a) {
    for (std::uint32_t i = first[a]; i < first[a + 1]; ++i) {
      const std::uint32_t b = next[i];
      if (i > first[a] && next[i - 1] == b) return false;  // a -> b twice
      if (std::binary_search(next.begin() + first[b], next.begin() + first[b + 1], a)) continue;
      if (++outs[a] > kMostAtAPinch || ++ins[b] > kMostAtAPinch) return false;
      outOf[a] = static_cast<std::uint32_t>(from.size());
      from.push_back(a), to.push_back(b);
    }
  }
  std::vector<std::uint32_t>().swap(next);
  std::vector<std::uint32_t>().swap(first);
  const std::size_t m = from.size();
  if (m < 3 || m >= kNone) return false;
  for (std::uint32_t a = 0; a < used; ++a) {
    if (outs[a] != ins[a]) return false;  // a boundary that ends
  }

  // Each boundary edge's successor along its loop: the edge leaving its end, or, where several
  // leave (a pinch), one next to it round the vertex. Round a pinch the boundary edges must
  // alternate, leaving and entering (counter-clockwise, a covered corner follows an edge leaving
  // and ends at one entering); an edge entering then goes on by an edge leaving next to it (here
  // the one just clockwise, bounding the same covered corner; the one just counter-clockwise
  // would do as well), so that the loops touch there and do not cross.
  std::vector<std::uint32_t> succ(m, kNone);
  struct AtPinch {
    std::uint32_t vertex, edge;
    bool leaving;
  };
  std::vector<AtPinch> pinches;
  for (std::uint32_t e = 0; e < m; ++e) {
    if (outs[to[e]] == 1) {
      succ[e] = outOf[to[e]];
    } else {
      pinches.push_back({to[e], e, false});
    }
    if (outs[from[e]] > 1) pinches.push_back({from[e], e, true});
  }
  std::sort(pinches.begin(), pinches.end(), [](const AtPinch& x, const AtPinch& y) {
    return x.vertex != y.vertex ? x.vertex < y.vertex : x.edge != y.edge ? x.edge < y.edge : x.leaving < y.leaving;
  });
  for (std::size_t g = 0; g < pinches.size();) {
    std::size_t h = g;
    while (h < pinches.size() && pinches[h].vertex == pinches[g].vertex) ++h;
    const Point2 v = point(pinches[g].vertex);
    const auto other = [&](const AtPinch& x) { return point(x.leaving ? to[x.edge] : from[x.edge]); };
    // Counter-clockwise from +u: the upper half-plane first, then by exact turns.
    const auto upper = [&](Point2 p) { return p.v > v.v || (p.v == v.v && p.u > v.u); };
    std::sort(pinches.begin() + g, pinches.begin() + h, [&](const AtPinch& x, const AtPinch& y) {
      const Point2 p = other(x), q = other(y);
      if (upper(p) != upper(q)) return upper(p);
      return orient2dSign(v, p, q) > 0;
    });
    const std::size_t k = h - g;
    for (std::size_t i = 0; i < k; ++i) {
      const AtPinch& x = pinches[g + i];
      const AtPinch& y = pinches[g + (i + 1) % k];
      if (x.leaving == y.leaving) return false;
      // (Along one line: opposite ways are fine, one way is two edges over each other.)
      if (orient2dSign(v, other(x), other(y)) == 0 && upper(other(x)) == upper(other(y))) return false;
      if (!x.leaving) continue;
      // x leaves, y (counter-clockwise next) enters: the loop entering by y leaves by x.
      succ[y.edge] = x.edge;
    }
    g = h;
  }
  std::vector<AtPinch>().swap(pinches);

  // The loops, each through a vertex once: a walk along the successors that comes back to a
  // vertex it left closes the loop from there at once (at a pinch of four edges, where either
  // pairing of its edges is a touch, not a crossing; past that, the pairs decide). Each loop's
  // turn at its least vertex by (u, v) (a convex corner of a simple polygon) says which way it
  // winds: +1 counter-clockwise, -1 clockwise.
  std::vector<std::uint32_t> loopOf(m, kNone), walkOf(used, kNone), leftAt(used, 0), walk;
  struct Loop {
    std::uint32_t least;  // an edge leaving the least vertex
    int winds;
  };
  std::vector<Loop> loops;
  const auto before = [&](Point2 p, Point2 q) { return p.u < q.u || (p.u == q.u && p.v < q.v); };
  // Closes walk[at..] as a loop.
  const auto close = [&](std::size_t at) {
    const auto id = static_cast<std::uint32_t>(loops.size());
    std::size_t least = at;
    for (std::size_t i = at; i < walk.size(); ++i) {
      loopOf[walk[i]] = id;
      if (before(point(from[walk[i]]), point(from[walk[least]]))) least = i;
      walkOf[from[walk[i]]] = kNone;
    }
    const std::uint32_t into = walk[least == at ? walk.size() - 1 : least - 1], out = walk[least];
    walk.resize(at);
    const int turn = orient2dSign(point(from[into]), point(from[out]), point(to[out]));
    loops.push_back({out, turn});
    return turn != 0;
  };
  for (std::uint32_t start = 0; start < m; ++start) {
    if (loopOf[start] != kNone) continue;
    walk.clear();
    for (std::uint32_t e = start;;) {
      const std::uint32_t v = from[e];
      if (walkOf[v] == start) {  // back at v: the walk since it left v is a loop
        if (outs[v] != 2 || !close(leftAt[v])) return false;
      }
      walkOf[v] = start, leftAt[v] = static_cast<std::uint32_t>(walk.size());
      walk.push_back(e);
      e = succ[e];
      if (e == kNone || (loopOf[e] != kNone && e != start)) return false;
      if (e == start) {
        if (!close(0)) return false;
        break;
      }
    }
  }

  // Simple and apart: no two boundary edges meet but at a vertex they share (and those do not
  // fold back along each other). Edges are bucketed on a grid over their boxes; a pair that
  // meets shares a cell, as both boxes hold the meeting point and the cells are a monotonic
  // function of it. (A boundary crowded into a few cells would cost its square: past a budget
  // the pairs decide.)
  double ulo = INFINITY, uhi = -INFINITY, vlo = INFINITY, vhi = -INFINITY;
  for (const std::uint32_t a : from) {
    const Point2 p = point(a);
    ulo = std::min(ulo, p.u), uhi = std::max(uhi, p.u), vlo = std::min(vlo, p.v), vhi = std::max(vhi, p.v);
  }
  const auto side = static_cast<std::uint32_t>(std::clamp(std::sqrt(static_cast<double>(m)), 1.0, 1024.0));
  const double su = uhi > ulo ? side / (uhi - ulo) : 0, sv = vhi > vlo ? side / (vhi - vlo) : 0;
  // (NaN, from a range too narrow or too wide for its scale, is cell 0: still monotonic.)
  const auto cell = [side](double x, double lo, double scale) {
    const double t = (x - lo) * scale;
    return t >= 1 ? static_cast<std::uint32_t>(std::min(std::floor(t), side - 1.0)) : 0u;
  };
  // (The cells' edges in one array, cell k's at start[k]..start[k + 1]: a count, then a fill;
  // first their number, which long edges over many cells could make too large.)
  const std::size_t cellCount = static_cast<std::size_t>(side) * side;
  std::size_t budget = 64 * m + (1u << 20);
  struct Span {
    std::uint32_t c0, c1, r0, r1;
  };
  const auto spanOf = [&](std::uint32_t e) {
    const Point2 p = point(from[e]), q = point(to[e]);
    return Span{cell(std::min(p.u, q.u), ulo, su), cell(std::max(p.u, q.u), ulo, su), cell(std::min(p.v, q.v), vlo, sv),
                cell(std::max(p.v, q.v), vlo, sv)};
  };
  std::uint64_t entries = 0;
  for (std::uint32_t e = 0; e < m; ++e) {
    const Span c = spanOf(e);
    entries += std::uint64_t{c.c1 - c.c0 + 1} * (c.r1 - c.r0 + 1);
    if (entries > budget) return false;
  }
  const auto forCells = [&](std::uint32_t e, const auto& visit) {
    const Span c = spanOf(e);
    for (std::uint32_t r = c.r0; r <= c.r1; ++r) {
      for (std::uint32_t k = c.c0; k <= c.c1; ++k) visit(static_cast<std::size_t>(r) * side + k);
    }
  };
  std::vector<std::size_t> start(cellCount + 1, 0);
  for (std::uint32_t e = 0; e < m; ++e) forCells(e, [&](std::size_t k) { ++start[k + 1]; });
  for (std::size_t k = 0; k < cellCount; ++k) start[k + 1] += start[k];
  std::vector<std::uint32_t> inCells(start[cellCount]);
  {
    std::vector<std::size_t> at(start.begin(), start.end() - 1);
    for (std::uint32_t e = 0; e < m; ++e) forCells(e, [&](std::size_t k) { inCells[at[k]++] = e; });
  }
  const auto cellEdges = [&](std::size_t k) {
    return std::span<const std::uint32_t>(inCells.data() + start[k], start[k + 1] - start[k]);
  };
  for (std::size_t k = 0; k < cellCount; ++k) {
    const auto in = cellEdges(k);
    for (std::size_t x = 0; x < in.size(); ++x) {
      for (std::size_t y = x + 1; y < in.size(); ++y) {
        if (budget-- == 0) return false;
        const std::uint32_t e = in[x], f = in[y];
        // A shared vertex s: the other ends p and t must not lie along one line on one side of it.
        std::uint32_t shared = kNone, pe = kNone, pf = kNone;
        if (from[e] == from[f] || from[e] == to[f])
          shared = from[e], pe = to[e], pf = from[e] == from[f] ? to[f] : from[f];
        if (to[e] == from[f] || to[e] == to[f]) shared = to[e], pe = from[e], pf = to[e] == from[f] ? to[f] : from[f];
        if (shared != kNone) {
          const Point2 q = point(shared), p = point(pe), t = point(pf);
          if (orient2dSign(p, q, t) != 0) continue;
          const bool backU = (p.u - q.u > 0) == (t.u - q.u > 0) && p.u != q.u && t.u != q.u;
          const bool backV = (p.v - q.v > 0) == (t.v - q.v > 0) && p.v != q.v && t.v != q.v;
          if (backU || backV) return false;
          continue;
        }
        if (segmentsMeet(point(from[e]), point(to[e]), point(from[f]), point(to[f]))) return false;
      }
    }
  }

  if (loops.size() == 1) return loops[0].winds > 0;
  // Nested right: inside a counter-clockwise loop the count must be 1, so the loops round it
  // must wind 0 in all (a hole's clockwise loop round an island's, an outer loop round the
  // hole). Their winding number is taken at a point o of the loop's own edge p -> q just past
  // p (o = p + e (q - p), e > 0 as small as need be), which lies off every other loop, as they
  // meet the loop at vertices only: the crossings of the ray from o towards +u, counted by side
  // (upward edges with o on their left +1, downward ones with o on their right -1), among the
  // edges in the cells the ray passes (those of p's row from p's column: o is that close).
  // Each test is exact: heights against o's are p's, or, level with p, below o when the edge
  // p -> q climbs; the side of o is the side of p, or, for an edge through p, the side of q.
  std::vector<std::uint32_t> seen(m, kNone);  // (an edge in several cells counted once a ray)
  for (std::uint32_t id = 0; id < loops.size(); ++id) {
    if (loops[id].winds < 0) continue;
    const Point2 p = point(from[loops[id].least]), q = point(to[loops[id].least]);
    const auto above = [&](Point2 x) {  // sign of x.v - o.v
      return x.v != p.v ? (x.v > p.v ? 1 : -1) : q.v > p.v ? -1 : q.v < p.v ? 1 : 0;
    };
    const std::uint32_t row = cell(p.v, vlo, sv);
    int around = 0;
    for (std::uint32_t c = cell(p.u, ulo, su); c < side; ++c) {
      for (const std::uint32_t e : cellEdges(static_cast<std::size_t>(row) * side + c)) {
        if (budget-- == 0) return false;
        if (loopOf[e] == id || seen[e] == id) continue;
        seen[e] = id;
        const Point2 a = point(from[e]), b = point(to[e]);
        const int va = above(a), vb = above(b);
        const bool up = va <= 0 && vb > 0, down = vb <= 0 && va > 0;
        if (!up && !down) continue;
        const bool aIsP = a.u == p.u && a.v == p.v, bIsP = b.u == p.u && b.v == p.v;
        const int turn = aIsP ? orient2dSign(p, b, q) : bIsP ? orient2dSign(a, p, q) : orient2dSign(a, b, p);
        if (turn == 0) return false;  // (along q's line: left to the pairs)
        around += up && turn > 0 ? 1 : down && turn < 0 ? -1 : 0;
      }
    }
    if (around > 0) return false;
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
