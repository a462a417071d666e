// The planar index's batches (terrain.hpp, index_face.hpp): software-pipelined over groups of
// points, the lean grid's planes and heights in SIMD, sixteen at a time.
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

namespace qota {

namespace {

// cornerPlane and the plane's height at (u, v) for kLanes points at once, in SIMD (AVX2 where the
// processor has it, SSE2 otherwise; chosen at load time). Each lane performs the same IEEE
// operations in the same order as cornerPlane and PlanarCore::leanHeight, with no fused
// multiply-add, so the same bits. Inputs are structure-of-arrays: corner k of lane i at
// [k * kLanes + i]. ok[i] is false where the lane needs the scalar path: a sliver's plane, or a
// height that the clamp to the corners' range could change.
// The two builds are chosen once, by a function pointer set when the library is loaded (not an
// ifunc: those run before ThreadSanitizer's runtime is up, and crash it).
constexpr int kLanes = 16;

using Vec4 = double __attribute__((vector_size(32)));

using Mask4 = long long __attribute__((vector_size(32)));

[[gnu::always_inline]] inline void planeHeightsLanes(const double* cu, const double* cv, const double* ch,
                                                     const double* u, const double* v, double* h, bool* ok) {
  for (int i = 0; i < kLanes; i += 4) {
    Vec4 c[3][3];  // [k][u, v, h]
    for (int k = 0; k < 3; ++k) {
      std::memcpy(&c[k][0], cu + k * kLanes + i, sizeof(Vec4));
      std::memcpy(&c[k][1], cv + k * kLanes + i, sizeof(Vec4));
      std::memcpy(&c[k][2], ch + k * kLanes + i, sizeof(Vec4));
    }
    Vec4 pu, pv;
    std::memcpy(&pu, u + i, sizeof(Vec4));
    std::memcpy(&pv, v + i, sizeof(Vec4));
    const Vec4 d1u = c[1][0] - c[0][0], d1v = c[1][1] - c[0][1], d1h = c[1][2] - c[0][2];
    const Vec4 d2u = c[2][0] - c[0][0], d2v = c[2][1] - c[0][1], d2h = c[2][2] - c[0][2];
    const Vec4 nu = d1v * d2h - d1h * d2v, nv = d1h * d2u - d1u * d2h, nh = d1u * d2v - d1v * d2u;
    const Vec4 minusOne = {-1, -1, -1, -1};
    const Vec4 q = minusOne / nh, a = nu * q, b = nv * q;
    const Vec4 height = c[0][2] + a * (pu - c[0][0]) + b * (pv - c[0][1]);
    const Vec4 h1 = c[1][2] < c[2][2] ? c[1][2] : c[2][2], h2 = c[1][2] > c[2][2] ? c[1][2] : c[2][2];
    const Vec4 lo = h1 < c[0][2] ? h1 : c[0][2], hi = h2 > c[0][2] ? h2 : c[0][2];
    const Vec4 zero = {0, 0, 0, 0};
    // Finite slopes (x - x is 0 only for finite x), an up-facing plane, a height in range.
    const Mask4 good = (nh > zero) & (a - a == zero) & (b - b == zero) & (height >= lo) & (height <= hi);
    std::memcpy(h + i, &height, sizeof(Vec4));
    for (int j = 0; j < 4; ++j) ok[i + j] = good[j] != 0;
  }
}

using PlaneHeights = void (*)(const double*, const double*, const double*, const double*, const double*, double*,
                              bool*);

[[gnu::target("avx2")]] void planeHeightsAvx2(const double* cu, const double* cv, const double* ch, const double* u,
                                              const double* v, double* h, bool* ok) {
  planeHeightsLanes(cu, cv, ch, u, v, h, ok);
}

void planeHeightsBaseline(const double* cu, const double* cv, const double* ch, const double* u, const double* v,
                          double* h, bool* ok) {
  planeHeightsLanes(cu, cv, ch, u, v, h, ok);
}

PlaneHeights choosePlaneHeights() {
  __builtin_cpu_init();
  return __builtin_cpu_supports("avx2") ? planeHeightsAvx2 : planeHeightsBaseline;
}

const PlaneHeights planeHeights = choosePlaneHeights();

// One group of up to kLanes points on a lean grid: first every point's cell and the cache lines
// of its corners, then the planes and heights in SIMD. ok[i]: points[i] lies clearly inside a
// present triangle and h[i] is its height there; else the exact path must answer it (near a
// side, off the grid, in a hole, or a plane that needs cornerPlane's checks or the clamp). hole[i]:
// it lies clearly inside a slot without a triangle, where the exact path finds none (its cell
// alone is tested, and the cell's other half cannot hold it). Unused lanes, and lanes without a
// triangle, compute on the corners of cell 0 and are thrown away.
// ahead, aheadN: the next group's points, whose corners are fetched meanwhile (their loads
// overlap this group's work instead of waiting at its start): for points scattered over a
// grid's cells (a sampler's tile; the index's own batches measured no gain).
[[gnu::always_inline]] inline void leanGroup(const detail::GridPath& grid, std::span<const Point2> corners,
                                             std::span<const double> heights, const Point2* points, std::size_t n,
                                             const Point2* ahead, std::size_t aheadN, double* h, bool* ok,
                                             bool* hole = nullptr) {
  alignas(32) double cu[3 * kLanes], cv[3 * kLanes], ch[3 * kLanes], pu[kLanes], pv[kLanes];
  bool lane[kLanes];
  // The points' cells, field by field (an array of Cell makes the compiler keep every field in
  // memory).
  std::uint64_t cellCol[kLanes], cellRow[kLanes], cellSlot[kLanes];
  std::uint32_t cellHalf[kLanes];
  for (std::size_t i = 0; i < n; ++i) {
    const detail::GridPath::Cell c = grid.cell(points[i].u, points[i].v);
    lane[i] = false;
    cellCol[i] = c.col, cellRow[i] = c.row, cellHalf[i] = c.half, cellSlot[i] = c.slot;
    if (!c.inGrid) continue;
    lane[i] = c.clear;  // its slot's presence is checked below
    grid.prefetchLean(c, corners, heights);
  }
  for (std::size_t i = 0; i < aheadN; ++i) {
    const detail::GridPath::Cell c = grid.cell(ahead[i].u, ahead[i].v);
    if (c.inGrid) grid.prefetchLean(c, corners, heights);
  }
  for (std::size_t i = 0; i < kLanes; ++i) {
    if (i < n && lane[i]) {
      const bool present = grid.slotPresent(cellSlot[i]);
      if (hole) hole[i] = !present;
      lane[i] = present;
    } else if (hole) {
      hole[i] = false;
    }
    const bool use = i < n && lane[i];
    for (int k = 0; k < 3; ++k) {
      grid.leanCorner(use ? cellCol[i] : 0, use ? cellRow[i] : 0, use ? cellHalf[i] : 0, k, corners, heights,
                      cu[k * kLanes + i], cv[k * kLanes + i], ch[k * kLanes + i]);
    }
    pu[i] = use ? points[i].u : cu[i];
    pv[i] = use ? points[i].v : cv[i];
  }
  planeHeights(cu, cv, ch, pu, pv, h, ok);
  for (std::size_t i = 0; i < kLanes; ++i) ok[i] = ok[i] && i < n && lane[i];
}

}  // namespace

void detail::GridPath::leanHeights(std::span<const Point2> corners, std::span<const double> heights,
                                   std::span<const Point2> points, double* out, std::uint8_t* decided) const {
  double h[kLanes];
  bool ok[kLanes], hole[kLanes];
  for (std::size_t g = 0; g < points.size(); g += kLanes) {
    const std::size_t n = std::min<std::size_t>(kLanes, points.size() - g);
    if (!isLean()) {
      for (std::size_t i = 0; i < n; ++i) decided[g + i] = kUndecided;
      continue;
    }
    const std::size_t next = std::min<std::size_t>(kLanes, points.size() - std::min(points.size(), g + kLanes));
    leanGroup(*this, corners, heights, &points[g], n, next ? &points[g + kLanes] : nullptr, next, h, ok, hole);
    for (std::size_t i = 0; i < n; ++i) {
      out[g + i] = h[i];
      decided[g + i] = ok[i] ? kHeight : hole[i] ? kNoTerrain : kUndecided;
    }
  }
}

template <class ZOf>
void PlanarCore::heightsBelowBatch(std::span<const Point2> points, const ZOf& zOf,
                                   std::span<std::optional<double>> heights) const {
  // Software pipelining: a single query waits for three or four dependent cache misses in turn
  // (the jump table's cell, a node, the leaf's references, its triangles); a batch issues the
  // loads of many points before waiting for any, so that their misses overlap. The grids work
  // in groups of points, the quadtree in a pipeline of stages.
  constexpr std::size_t kGroup = 16;
  if (grid_.isLean()) {
    // The lean grid: the points clearly inside a triangle get their planes and heights in SIMD,
    // sixteen at a time (leanGroup), the rest one by one.
    static_assert(kGroup == kLanes);
    double ph[kLanes];
    bool ok[kLanes];
    for (std::size_t g = 0; g < points.size(); g += kGroup) {
      const std::size_t n = std::min(kGroup, points.size() - g);
      leanGroup(grid_, corners2_, cornerH_, &points[g], n, nullptr, 0, ph, ok);
      for (std::size_t i = 0; i < n; ++i) {
        double h = ph[i];
        if (!ok[i] && gridAnswer<false>(points[g + i].u, points[g + i].v, h) == kNoTriangle) {
          heights[g + i] = std::nullopt;
          continue;
        }
        heights[g + i] = h <= zOf(g + i) ? std::optional<double>(h) : std::nullopt;
      }
    }
    return;
  }
  if (grid_.on()) {
    // A grid with records: first every point's cell and its triangle ids, then their records.
    std::uint64_t cellSlot[kGroup];
    std::uint32_t cellHalf[kGroup];
    bool inGrid[kGroup];
    for (std::size_t g = 0; g < points.size(); g += kGroup) {
      const std::size_t n = std::min(kGroup, points.size() - g);
      for (std::size_t i = 0; i < n; ++i) {
        const Point2 p = points[g + i];
        const detail::GridPath::Cell c = grid_.cell(p.u, p.v);
        inGrid[i] = c.inGrid, cellHalf[i] = c.half, cellSlot[i] = c.slot;
        if (!c.inGrid) continue;
        grid_.prefetchSlots(c);
      }
      for (std::size_t i = 0; i < n; ++i) {
        if (!inGrid[i]) continue;
        const std::uint64_t first = cellSlot[i] - cellHalf[i];  // the cell's two halves
        for (int half = 0; half < 2; ++half) {
          const std::uint32_t t = grid_.triangleIn(first + half);
          if (t == kNoTriangle) continue;
          __builtin_prefetch(&tris_[t]);
        }
      }
      for (std::size_t i = 0; i < n; ++i) {
        const Point2 p = points[g + i];
        double h = 0;
        heights[g + i] =
            gridAnswer<false>(p.u, p.v, h) != kNoTriangle && h <= zOf(g + i) ? std::optional<double>(h) : std::nullopt;
      }
    }
    return;
  }
  // The quadtree: five stages kAhead points apart, so that some 4 kAhead points have a load in
  // flight at any time: the jump table's cell (A), the node below it (B), the rest of the descent
  // and the leaf's references (C), the leaf's triangles (D); then the answer (E), by nearestIn as
  // a single query. (Groups of 16 with the descent done point by point took 245 ns a point on a
  // TIN of a million triangles, this 150; kAhead 8 and 16 measured alike there, 4 worse.)
  constexpr std::size_t kAhead = 16, kRing = 128;  // kRing: a power of two above 4 kAhead
  static_assert(kRing > 4 * kAhead && (kRing & (kRing - 1)) == 0);
  Quadtree::Walk walk[kRing];
  Quadtree::Node leafOf[kRing];
  bool inTree[kRing], more[kRing];
  const std::size_t n = points.size();
  for (std::size_t i = 0; i < n + 4 * kAhead; ++i) {
    if (i < n) {  // A
      const std::size_t r = i % kRing;
      inTree[r] = tree_.contains(points[i].u, points[i].v);
      if (inTree[r]) walk[r] = tree_.startWalk(points[i].u, points[i].v);
    }
    if (i >= kAhead && i - kAhead < n) {  // B
      const std::size_t k = i - kAhead, r = k % kRing;
      leafOf[r] = Quadtree::Node{0, 0};
      more[r] = inTree[r] && tree_.stepWalk(points[k].u, points[k].v, walk[r], leafOf[r]);
    }
    if (i >= 2 * kAhead && i - 2 * kAhead < n) {  // C
      const std::size_t k = i - 2 * kAhead, r = k % kRing;
      while (more[r]) more[r] = tree_.stepWalk(points[k].u, points[k].v, walk[r], leafOf[r]);
      // (Both ends: a leaf's references cross into a second line about one time in three.)
      const std::span<const std::uint32_t> refs = tree_.leafRange(leafOf[r]);
      __builtin_prefetch(refs.data());
      if (!refs.empty()) __builtin_prefetch(&refs.back());
    }
    if (i >= 3 * kAhead && i - 3 * kAhead < n) {  // D
      prefetchTriangles(tree_.leafRange(leafOf[(i - 3 * kAhead) % kRing]));
    }
    if (i >= 4 * kAhead) {  // E
      const std::size_t k = i - 4 * kAhead, r = k % kRing;
      double h = 0;
      const Point2 p = points[k];
      const std::uint32_t t =
          inTree[r] ? nearestIn<true>(tree_.leafRange(leafOf[r]), Quadtree::singleLayer(leafOf[r]), p.u, p.v, zOf(k), h)
                    : kNoTriangle;
      heights[k] = t == kNoTriangle ? std::nullopt : std::optional<double>(h);
    }
  }
}

void PlanarCore::batchBelow(std::span<const Point2> points, double z, std::span<std::optional<double>> out) const {
  heightsBelowBatch(
      points, [z](std::size_t) { return z; }, out);
}

void PlanarCore::batchBelow(std::span<const Point2> points, std::span<const double> zs,
                            std::span<std::optional<double>> out) const {
  heightsBelowBatch(
      points, [zs](std::size_t i) { return zs[i]; }, out);
}

}  // namespace qota
