#include "qota/terrain.hpp"

#include <array>
#include <thread>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>
#include <string>

#include "float_bounds.hpp"
#include "qota/batch.hpp"
#include "qota/index.hpp"
#include "qota/error.hpp"
#include "qota/memory_budget.hpp"

namespace qota {

static_assert(EditableTerrain<CartesianIndex>);  // (and every PlanarIndex<M>: the same core)

namespace {

constexpr double kUnitRoundoff = 0x1p-53;
constexpr double kInf = std::numeric_limits<double>::infinity();

std::uint32_t spreadBits16(std::uint32_t x) {
  x &= 0xffff;
  x = (x | (x << 8)) & 0x00ff00ff;
  x = (x | (x << 4)) & 0x0f0f0f0f;
  x = (x | (x << 2)) & 0x33333333;
  x = (x | (x << 1)) & 0x55555555;
  return x;
}

// The plane of a triangle from its mapped corners: slopes a = dh/du and b = dh/dv, and the
// height h0 it takes at corner 0. One body for the triangle records and the lean grid, so that
// both give the same bits. (The records also keep the corners' height range, rounded outward to
// floats, to clamp the plane with.)
struct PlaneFit {
  double a, b, h0;
};
// The slopes alone, and the normal's h component: fitPlane without its sliver check.
struct RawSlopes {
  double a, b, nh;
};
[[gnu::always_inline]] inline RawSlopes rawSlopes(double u0, double v0, double h0, double u1, double v1, double h1,
                                                  double u2, double v2, double h2) {
  const double d1u = u1 - u0, d1v = v1 - v0, d1h = h1 - h0;
  const double d2u = u2 - u0, d2v = v2 - v0, d2h = h2 - h0;
  const double nu = d1v * d2h - d1h * d2v, nv = d1h * d2u - d1u * d2h, nh = d1u * d2v - d1v * d2u;
  // One division for both slopes, not two; -x * q is x * -q.
  const double q = -1.0 / nh;
  return {nu * q, nv * q, nh};
}
[[gnu::always_inline]] inline PlaneFit fitPlane(double u0, double v0, double h0, double u1, double v1, double h1,
                                                double u2, double v2, double h2) {
  const RawSlopes r = rawSlopes(u0, v0, h0, u1, v1, h1, u2, v2, h2);
  PlaneFit p{r.a, r.b, h0};
  if (!(r.nh > 0) || !std::isfinite(p.a) || !std::isfinite(p.b)) [[unlikely]] {
    // A sliver with nonzero exact area whose plane is vertical to within rounding. It stays in
    // the index, or its neighbours would open a crack; its height is its corners' mid-range.
    p.a = p.b = 0;
    p.h0 = 0.5 * (std::min(h0, std::min(h1, h2)) + std::max(h0, std::max(h1, h2)));
  }
  return p;
}
inline PlaneFit fitPlane(const double u[3], const double v[3], const double h[3]) {
  return fitPlane(u[0], v[0], h[0], u[1], v[1], h[1], u[2], v[2], h[2]);
}

// fitPlane and the plane's height at (u, v) for kLanes points at once, in SIMD (AVX2 where the
// processor has it, SSE2 otherwise; chosen at load time). Each lane performs the same IEEE
// operations in the same order as fitPlane and PlanarCore::leanHeight, with no fused
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

std::string describePoint(const Eigen::Vector3d& p) {
  return "(" + std::to_string(p.x()) + ", " + std::to_string(p.y()) + ", " + std::to_string(p.z()) + ")";
}

// A triangle waiting for the build: mapped corner indices (counter-clockwise) and its polygon.

// True when the polygon's projection has an area below 1e-9 of its squared size: a wall seen
// edge-on, whose corners rounding has scattered off their common line (a vertical wall under a
// tilted gravity). Such a polygon is a wall, not a non-convex one.
bool nearlyFlat(std::span<const std::uint32_t> idx, std::span<const Point2> c) {
  // Unsigned fan areas, so that a bow-tie's halves cannot cancel out.
  double area2 = 0, ulo = INFINITY, uhi = -INFINITY, vlo = INFINITY, vhi = -INFINITY;
  for (std::size_t i = 0; i < idx.size(); ++i) {
    const Point2 a = c[idx[i]];
    if (i + 2 < idx.size()) area2 += std::fabs(orient2dApprox(c[idx[0]], c[idx[i + 1]], c[idx[i + 2]]));
    ulo = std::min(ulo, a.u), uhi = std::max(uhi, a.u), vlo = std::min(vlo, a.v), vhi = std::max(vhi, a.v);
  }
  const double size2 = (uhi - ulo) * (uhi - ulo) + (vhi - vlo) * (vhi - vlo);
  return area2 <= 1e-9 * size2;
}

// Sign of the convex polygon's orientation as seen along gravity: +1 counter-clockwise, -1
// clockwise, 0 when its projection has no area (or nearly none, see nearlyFlat). Throws when it
// is not convex. In linear time, with exact predicates: every corner turns the same way (or goes
// straight on), and the corners come in angular order around an extreme one (the lowest, then
// leftmost), which a polygon winding round more than once (a pentagram turns one way at every
// corner too) cannot do.
int convexOrientation(std::span<const std::uint32_t> idx, std::span<const Point2> c, std::size_t polygon) {
  const std::size_t n = idx.size();
  const auto notConvex = [&]() -> int {
    if (nearlyFlat(idx, c)) return 0;
    throw Error("polygon " + std::to_string(polygon) + " (" + std::to_string(n) +
                " vertices) is not convex as seen along gravity; split it into convex "
                "polygons or triangles");
  };
  int sign = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const int s = orient2dSign(c[idx[(i + n - 1) % n]], c[idx[i]], c[idx[(i + 1) % n]]);
    if (s == 0) continue;
    if (sign == 0) sign = s;
    if (s != sign) return notConvex();
  }
  if (sign == 0) return 0;  // every corner on one line
  std::size_t k = 0;
  for (std::size_t i = 1; i < n; ++i) {
    const Point2 p = c[idx[i]], q = c[idx[k]];
    if (p.v < q.v || (p.v == q.v && p.u < q.u)) k = i;
  }
  const Point2 p0 = c[idx[k]];
  for (std::size_t j = 1; j + 1 < n; ++j) {
    const int s = orient2dSign(p0, c[idx[(k + j) % n]], c[idx[(k + j + 1) % n]]);
    if (s != 0 && s != sign) return notConvex();
  }
  return sign;
}

}  // namespace

PlanarCore::PlanarCore(const Mesh& mesh, const PlanarFrame& frame, const IndexOptions& options) : frame_(frame) {
  const std::size_t np = mesh.polygonCount();
  std::uint64_t fanned = 0;
  for (std::size_t p = 0; p < np; ++p) fanned += mesh.polygon(p).size() > 2 ? mesh.polygon(p).size() - 2 : 0;
  startBuild(mesh.vertices, np, fanned, options);

  // Validate each polygon and fan it into counter-clockwise triangles.
  std::vector<Pending> pending;
  pending.reserve(np);
  for (std::size_t p = 0; p < np; ++p) {
    const auto idx = mesh.polygon(p);
    if (idx.size() < 3) {
      throw Error("polygon " + std::to_string(p) + " has " + std::to_string(idx.size()) +
                  " vertices; a polygon needs at least 3");
    }
    checkCorners(idx, p, mesh.vertices);
    const std::size_t before = pending.size();
    fanPolygon(idx, static_cast<std::uint32_t>(p), pending);
    if (pending.size() == before) ++stats_.leftOut;
  }
  finishBuild(pending, nullptr, options);
}

PlanarCore::PlanarCore(const GridMesh& grid, const PlanarFrame& frame, const IndexOptions& options) : frame_(frame) {
  const std::uint64_t w = static_cast<std::uint64_t>(std::max(grid.width, 0));
  const std::uint64_t h = static_cast<std::uint64_t>(std::max(grid.height, 0));
  if (grid.vertices.size() != w * h) {
    throw Error("terrain: a grid of " + std::to_string(grid.width) + " x " + std::to_string(grid.height) +
                " vertices given " + std::to_string(grid.vertices.size()));
  }
  // The polygons are the Mesh's (GridMesh::toMesh): the raster rule's triangles with data at
  // their three corners, square by square in row order. Counted first, to refuse as that mesh
  // would be refused before allocating.
  const auto data = [&](std::uint64_t v) { return GridMesh::hasData(grid.vertices[v]); };
  const std::uint64_t np = grid.polygonCount();
  startBuild(grid.vertices, np, np, options);

  // The same validation and fan (one triangle each) as the Mesh's polygons, and each triangle's
  // slot on the lattice as recognise would find it.
  std::vector<Pending> pending;
  std::vector<std::uint32_t> slots;
  pending.reserve(np);
  slots.reserve(np);
  std::uint32_t p = 0;
  const auto add = [&](std::uint32_t a, std::uint32_t b, std::uint32_t c, std::uint64_t slot) {
    if (!(data(a) && data(b) && data(c))) return;
    const std::uint32_t idx[3] = {a, grid.reverse ? c : b, grid.reverse ? b : c};
    checkCorners(idx, p, grid.vertices);
    const std::size_t before = pending.size();
    fanPolygon(idx, p, pending);
    if (pending.size() == before) {
      ++stats_.leftOut;
    } else {
      slots.push_back(static_cast<std::uint32_t>(slot));
    }
    ++p;
  };
  for (std::uint64_t r = 0; r + 1 < h; ++r) {
    for (std::uint64_t c = 0; c + 1 < w; ++c) {
      const auto tl = static_cast<std::uint32_t>(r * w + c), tr = tl + 1;
      const auto bl = static_cast<std::uint32_t>(tl + w), br = bl + 1;
      const std::uint64_t square = r * (w - 1) + c;
      add(tl, bl, br, 2 * square);
      add(tl, br, tr, 2 * square + 1);
    }
  }
  const Lattice lattice{w, h, std::move(slots)};
  finishBuild(pending, &lattice, options);
}

void PlanarCore::startBuild(std::span<const Eigen::Vector3d> vertices, std::uint64_t polygons, std::uint64_t fanned,
                            const IndexOptions& options) {
  const std::size_t nv = vertices.size();
  if (nv >= std::numeric_limits<std::uint32_t>::max() || polygons >= std::numeric_limits<std::uint32_t>::max()) {
    throw Error("terrain: " + std::to_string(nv) + " vertices and " + std::to_string(polygons) +
                " polygons exceed the 32-bit indices of the index");
  }
  stats_.polygons = polygons;
  stats_.vertices = nv;
  // Refuse what cannot fit before allocating: at least a grid's worth (the lean grid is the
  // smallest index), a general mesh's with its tree.
  memory::require("terrain", options.gridFastPath.value_or(true) ? memory::kGridIndex : memory::kCartesianIndex, nv,
                  fanned);

  // Map every vertex once, so that polygons sharing a vertex share its mapped coordinates exactly.
  corners2_.resize(nv);
  cornerH_.resize(nv);
  for (std::size_t i = 0; i < nv; ++i) {
    const Eigen::Vector3d m = frame_.toMapped(vertices[i]);
    corners2_[i] = {m.x(), m.y()};
    cornerH_[i] = m.z();
  }
}

void PlanarCore::checkCorners(std::span<const std::uint32_t> idx, std::size_t p,
                              std::span<const Eigen::Vector3d> vertices) const {
  const std::size_t nv = vertices.size();
  for (std::uint32_t i : idx) {
    if (i >= nv) {
      throw Error("polygon " + std::to_string(p) + " refers to vertex " + std::to_string(i) + " but the mesh has " +
                  std::to_string(nv) + " vertices");
    }
    if (!vertices[i].allFinite() || !std::isfinite(corners2_[i].u) || !std::isfinite(corners2_[i].v) ||
        !std::isfinite(cornerH_[i])) {
      throw Error("polygon " + std::to_string(p) + ": vertex " + std::to_string(i) + " has a non-finite coordinate " +
                  describePoint(vertices[i]));
    }
  }
}

void PlanarCore::finishBuild(std::vector<Pending>& pending, const Lattice* lattice, const IndexOptions& options) {
  stats_.triangles = pending.size();

  // The domain: the bounding box of every triangle, in the mapped frame.
  Box2 domain{std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
              -std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()};
  for (const auto& q : pending) {
    for (std::uint32_t c : q.corner) {
      domain.ulo = std::min(domain.ulo, corners2_[c].u);
      domain.uhi = std::max(domain.uhi, corners2_[c].u);
      domain.vlo = std::min(domain.vlo, corners2_[c].v);
      domain.vhi = std::max(domain.vhi, corners2_[c].v);
    }
  }
  if (pending.empty()) domain = Box2{};
  stats_.domain = domain;

  // Store triangles in Morton order of their centroids, so that the triangles of one leaf (and of
  // neighbouring leaves) sit next to each other in memory; a regular grid's in row order instead,
  // so that a walk along a row reads memory in order.
  // (A grid mesh's slots are known: only its vertices are left to check.)
  std::vector<std::uint32_t> recognised;
  if (options.gridFastPath.value_or(true) && !lattice) recognised = grid_.recognise(corners2_, pending);
  const bool onLattice = options.gridFastPath.value_or(true) && lattice && !pending.empty() &&
                         grid_.fitLattice(corners2_, lattice->width, lattice->height);
  const std::span<const std::uint32_t> slots =
      onLattice ? std::span<const std::uint32_t>(lattice->slots) : std::span<const std::uint32_t>(recognised);
  if (!pending.empty()) {
    const double su = domain.uhi > domain.ulo ? 65535.0 / (domain.uhi - domain.ulo) : 0.0;
    const double sv = domain.vhi > domain.vlo ? 65535.0 / (domain.vhi - domain.vlo) : 0.0;
    std::vector<std::uint64_t> keyed(pending.size());
    for (std::size_t t = 0; t < pending.size(); ++t) {
      std::uint64_t code = 0;
      if (slots.empty()) {
        double cu = 0, cv = 0;
        for (std::uint32_t c : pending[t].corner) {
          cu += corners2_[c].u / 3;
          cv += corners2_[c].v / 3;
        }
        const auto iu = static_cast<std::uint32_t>(std::clamp((cu - domain.ulo) * su, 0.0, 65535.0));
        const auto iv = static_cast<std::uint32_t>(std::clamp((cv - domain.vlo) * sv, 0.0, 65535.0));
        code = spreadBits16(iu) | (spreadBits16(iv) << 1);
      } else {
        code = slots[t];
      }
      keyed[t] = code << 32 | t;
    }
    // A raster's triangles usually come in row order already: then there is nothing to move.
    if (!std::is_sorted(keyed.begin(), keyed.end())) {
      std::sort(keyed.begin(), keyed.end());
      std::vector<Pending> sorted(pending.size());
      for (std::size_t t = 0; t < keyed.size(); ++t) sorted[t] = pending[keyed[t] & 0xffffffffu];
      pending.swap(sorted);
    }
    if (!slots.empty()) {
      grid_.fillSlots(keyed);
    }
  }

  // Hot and cold records. The edge tolerance bounds the rounding error of A u + B v + C for every
  // (u, v) in the domain: the rounded A, B, C (one rounding each, two for C's products) and the
  // evaluation (three roundings) stay within 8 units of the magnitude sum; 16 leaves a margin.
  umax_ = std::max(std::fabs(domain.ulo), std::fabs(domain.uhi));
  vmax_ = std::max(std::fabs(domain.vlo), std::fabs(domain.vhi));
  cold_.resize(pending.size());
  for (std::size_t t = 0; t < pending.size(); ++t) {
    const Pending& q = pending[t];
    cold_[t] = Cold{{q.corner[0], q.corner[1], q.corner[2]}, q.polygon};
  }
  // A grid whose cells all store their corners in the same order keeps no records at all: the
  // fast path computes a cell's plane from its corners (the same arithmetic, so the same bits),
  // and the records are made with the tree when something needs them.
  if (grid_.on()) grid_.setUpLean(cold_, corners2_, cornerH_);
  const bool deferred = grid_.on();
  std::vector<Box2> boxes(deferred ? 0 : pending.size());  // build only: bboxes for the overlap test
  if (!grid_.lean) {
    tris_.resize(pending.size());
    for (std::size_t t = 0; t < pending.size(); ++t) {
      const Box2 box = makeRecord(static_cast<std::uint32_t>(t), pending[t]);
      if (!deferred) boxes[t] = box;
    }
  }
  deferredOptions_ = options.tree;
  baseMemoryBytes_ =
      cold_.size() * sizeof(Cold) + corners2_.size() * (sizeof(Point2) + sizeof(double)) + grid_.memoryBytes();
  if (deferred) {
    // The grid answers every height query: the tree waits until something needs it.
    deferredTree_ = true;
    recordBytesBeforeTree_ = tris_.size() * sizeof(Tri);
    stats_.memoryBytes = baseMemoryBytes_ + recordBytesBeforeTree_;
  } else {
    setTreeFloor(boxes);
    tree_.build(
        static_cast<std::uint32_t>(cold_.size()), domain, options.tree,
        [this, &boxes](std::uint32_t t, const Box2& b) { return overlaps(t, boxes[t], b); }, floorU_, floorV_,
        [&boxes](std::uint32_t t) { return boxes[t]; });
    tree_.markLeaves([this](std::span<std::uint32_t> items) { return prepareLeaf(items); });
    stats_.tree = tree_.stats();
    stats_.memoryBytes = baseMemoryBytes_ + tris_.size() * sizeof(Tri) + stats_.tree.memoryBytes;
  }
  // The triangles' height range, rounded outward to floats (once: the rounding is monotonic).
  double lo = INFINITY, hi = -INFINITY;
  for (std::uint32_t t = 0; t < cold_.size(); ++t) {
    for (std::uint32_t c : cold_[t].corner) lo = std::min(lo, cornerH_[c]), hi = std::max(hi, cornerH_[c]);
  }
  if (!cold_.empty()) {
    hmin_ = std::min(hmin_, static_cast<double>(floatBelow(lo)));
    hmax_ = std::max(hmax_, static_cast<double>(floatAbove(hi)));
  }
}

const PlanarCore::Tri& PlanarCore::gridRecord(std::uint32_t t, Tri& scratch) const {
  // A lean grid never reads the records, not even once the tree has made them: they may be
  // being made on another thread.
  if (!grid_.lean) return tris_[t];
  scratch = computeRecord(cold_[t].corner);
  return scratch;
}

PlanarCore::Tri PlanarCore::recordOf(std::uint32_t t) const {
  return grid_.lean || t >= tris_.size() ? computeRecord(cold_[t].corner) : tris_[t];
}

[[gnu::always_inline]] inline void PlanarCore::leanCorner(std::uint64_t col, std::uint64_t row, std::uint32_t half,
                                                          int k, double& u, double& v, double& h) const {
  grid_.leanCorner(col, row, half, k, corners2_, cornerH_, u, v, h);
}

// The height at (u, v) on the triangle in half `half` of cell (col, row), and its plane: the
// records' arithmetic (fitPlane, then leanHeight's clamp), without fitPlane's checks and the
// clamp where they change nothing: finite slopes of an up-facing plane (nh > 0) give a finite
// height, slopes that are not finite give none, so nh > 0 and a height within the corners' range
// stand for all of them.
[[gnu::always_inline]] inline double PlanarCore::leanAnswer(std::uint64_t col, std::uint64_t row, std::uint32_t half,
                                                            double u, double v, LeanPlane& p) const {
  double u0, v0, h0, u1, v1, h1, u2, v2, h2;
  leanCorner(col, row, half, 0, u0, v0, h0);
  leanCorner(col, row, half, 1, u1, v1, h1);
  leanCorner(col, row, half, 2, u2, v2, h2);
  const RawSlopes r = rawSlopes(u0, v0, h0, u1, v1, h1, u2, v2, h2);
  p = {r.a, r.b, h0, u0, v0, std::min(h0, std::min(h1, h2)), std::max(h0, std::max(h1, h2))};
  const double h = h0 + r.a * (u - u0) + r.b * (v - v0);
  if (r.nh > 0 && h >= p.lo && h <= p.hi) [[likely]]
    return h;
  // A sliver, or a height the clamp may move: the checked plane.
  const PlaneFit f = fitPlane(u0, v0, h0, u1, v1, h1, u2, v2, h2);
  p.a = f.a, p.b = f.b, p.h0 = f.h0;
  return leanHeight(p, u, v);
}

// heightOf's expression on the record the same corners make. The clamp to the corners' height
// range rounded outward to floats changes nothing for a value inside the range itself, the common
// case.
[[gnu::always_inline]] inline double PlanarCore::leanHeight(const LeanPlane& p, double u, double v) {
  const double h = p.h0 + p.a * (u - p.u0) + p.b * (v - p.v0);
  if (h >= p.lo && h <= p.hi) [[likely]]
    return h;
  return std::clamp(h, static_cast<double>(floatBelow(p.lo)), static_cast<double>(floatAbove(p.hi)));
}

template <bool NeedId>
[[gnu::always_inline]] inline std::uint32_t PlanarCore::gridAnswer(double u, double v, double& h,
                                                                   Quadtree::Cursor* cursor) const {
  if (grid_.lean) {
    const detail::GridPath::Cell g = grid_.cell(u, v);
    if (g.inGrid && g.clear) [[likely]] {
      const std::uint64_t slot = g.slot;
      if (cursor && cursor->memo.key == slot && cursor->memo.owner == this && cursor->memo.generation == generation_) {
        const double* m = cursor->memo.value;
        h = leanHeight({m[0], m[1], m[2], m[3], m[4], m[5], m[6]}, u, v);
        return NeedId ? cursor->memo.item : kFound;
      }
      std::uint32_t t = kFound;
      bool present;
      if constexpr (NeedId) {
        t = grid_.cellTri[slot];
        present = t != kNone;
      } else {
        present = grid_.slotPresent(slot);
      }
      if (present) [[likely]] {
        LeanPlane p;
        h = leanAnswer(g.col, g.row, g.half, u, v, p);
        if (cursor) {
          auto& m = cursor->memo;
          m.owner = this, m.generation = generation_, m.key = slot;
          m.item = NeedId ? t : grid_.cellTri[slot];
          // One store each: a copy through a local array made the compiler store it in halves and
          // reload it whole, a store-forwarding stall on every query of a walk.
          m.value[0] = p.a, m.value[1] = p.b, m.value[2] = p.h0, m.value[3] = p.u0;
          m.value[4] = p.v0, m.value[5] = p.lo, m.value[6] = p.hi;
        }
        return t;
      }
    }
    return gridAnswerNearEdge(u, v, g.fc, g.fr, h);
  }
  return gridAnswerFromRecords(u, v, h);
}

[[gnu::noinline]] std::uint32_t PlanarCore::gridAnswerFromRecords(double u, double v, double& h) const {
  Tri scratch;
  const Tri* rec = nullptr;
  const std::uint32_t t = gridTriangle(u, v, scratch, rec);
  if (t != kOffGrid) h = heightOf(*rec, u, v);
  return t;
}

[[gnu::noinline]] std::uint32_t PlanarCore::gridAnswerNearEdge(double u, double v, double fc, double fr,
                                                               double& h) const {
  Tri scratch;
  const Tri* rec = nullptr;
  const std::uint32_t t = gridTriangleNearEdge(u, v, fc, fr, scratch, rec);
  if (t != kOffGrid) h = heightOf(*rec, u, v);
  return t;
}

std::uint32_t PlanarCore::gridTriangle(double u, double v, Tri& scratch, const Tri*& rec) const {
  const double du = u - grid_.u0, dv = v - grid_.v0;
  const double fc = grid_.inv[0] * du + grid_.inv[1] * dv, fr = grid_.inv[2] * du + grid_.inv[3] * dv;
  if (fc >= 0 && fr >= 0 && fc < grid_.w - 1 && fr < grid_.h - 1) [[likely]] {
    const auto col = static_cast<std::uint32_t>(fc), row = static_cast<std::uint32_t>(fr);
    // The half of the cell with corner (col, row + 1) lies where the row fraction exceeds the
    // column fraction.
    const std::uint32_t half = fr - row > fc - col ? 0 : 1;
    const std::uint64_t slot = 2 * (static_cast<std::uint64_t>(row) * (grid_.w - 1) + col) + half;
    const std::uint32_t t = grid_.cellTri[slot];
    if (t != kNone) {
      // Clearly inside, beyond twice the edge tests' error bound: no other triangle of a grid
      // can hold the point.
      const Tri& r = gridRecord(t, scratch);
      rec = &r;
      if (r.A[0] * u + r.B[0] * v + r.C[0] > 2 * r.tol && r.A[1] * u + r.B[1] * v + r.C[1] > 2 * r.tol &&
          r.A[2] * u + r.B[2] * v + r.C[2] > 2 * r.tol) {
        return t;
      }
    }
  }
  return gridTriangleNearEdge(u, v, fc, fr, scratch, rec);
}

std::uint32_t PlanarCore::gridTriangleNearEdge(double u, double v, double fc, double fr, Tri& scratch,
                                               const Tri*& rec) const {
  // Beyond a cell off the grid nothing can hold the point; NaN lands here too.
  if (!(fc >= -1 && fr >= -1 && fc <= grid_.w && fr <= grid_.h)) return kOffGrid;
  const double cellsU = grid_.w - 1, cellsV = grid_.h - 1;
  const auto col = static_cast<std::int64_t>(std::floor(std::clamp(fc, 0.0, cellsU - 0.5)));
  const auto row = static_cast<std::int64_t>(std::floor(std::clamp(fr, 0.0, cellsV - 0.5)));
  // On or near an edge (a pixel centre, a cell side), in a hole, or just off the grid: every
  // triangle that can hold the point is in the estimated cell or in a neighbour across a side the
  // point is within 1e-5 cell of (the vertices lie on the affine grid to within 1e-6 of a cell).
  // The exact closed test decides, and the smallest polygon id among those holding the point
  // answers, as in the quadtree's single-layer leaves.
  constexpr double kNear = 1e-5;
  const std::int64_t c0 = col - (fc - col < kNear), c1 = col + (col + 1 - fc < kNear);
  const std::int64_t r0 = row - (fr - row < kNear), r1 = row + (row + 1 - fr < kNear);
  std::uint32_t best = kNone;
  for (std::int64_t r = std::max<std::int64_t>(r0, 0); r <= std::min<std::int64_t>(r1, grid_.h - 2); ++r) {
    for (std::int64_t c = std::max<std::int64_t>(c0, 0); c <= std::min<std::int64_t>(c1, grid_.w - 2); ++c) {
      for (int half = 0; half < 2; ++half) {
        const std::uint64_t slot = 2 * (static_cast<std::uint64_t>(r) * (grid_.w - 1) + c) + half;
        const std::uint32_t t = grid_.cellTri[slot];
        if (t == kNone) continue;
        Tri candidateScratch;
        const Tri& candidate = gridRecord(t, candidateScratch);
        if (!contains(candidate, t, u, v)) continue;
        if (best == kNone || cold_[t].polygon < cold_[best].polygon) best = t, scratch = candidate;
      }
    }
  }
  rec = &scratch;
  return best == kNone ? kOffGrid : best;
}

void PlanarCore::fanPolygon(std::span<const std::uint32_t> idx, std::uint32_t p, std::vector<Pending>& pending) const {
  const int sign = idx.size() == 3 ? orient2dSign(corners2_[idx[0]], corners2_[idx[1]], corners2_[idx[2]])
                                   : convexOrientation(idx, corners2_, p);
  if (sign == 0) return;
  for (std::size_t k = 1; k + 1 < idx.size(); ++k) {
    const std::uint32_t a = idx[0], b = idx[k], c = idx[k + 1];
    // Fan triangles over collinear corners have no area: the rest of the fan covers them.
    if (idx.size() > 3 && orient2dSign(corners2_[a], corners2_[b], corners2_[c]) == 0) continue;
    pending.push_back(sign > 0 ? Pending{{a, b, c}, p} : Pending{{a, c, b}, p});
  }
}

// The hot and cold records of triangle t. The edge tolerance bounds the rounding error of
// A u + B v + C for every (u, v) in the domain: the rounded A, B, C (one rounding each, two for
// C's products) and the evaluation (three roundings) stay within 8 units of the magnitude sum;
// 16 leaves a margin. Returns the triangle's bounding box.
Box2 PlanarCore::makeRecord(std::uint32_t t, const Pending& q) {
  cold_[t] = Cold{{q.corner[0], q.corner[1], q.corner[2]}, q.polygon};
  tris_[t] = computeRecord(q.corner);
  return boxOf(t);
}

PlanarCore::Tri PlanarCore::computeRecord(const std::uint32_t corner[3]) const {
  Tri r;
  edgeRecord(corner, r);
  planeRecord(corner, r);
  return r;
}

// The edge equations, their tolerance and corner 0: cheap, recomputed per query on a compact
// grid.
void PlanarCore::edgeRecord(const std::uint32_t corner[3], Tri& r) const {
  double tol = 0;
  for (int k = 0; k < 3; ++k) {
    const Point2 p0 = corners2_[corner[k]], p1 = corners2_[corner[(k + 1) % 3]];
    r.A[k] = p0.v - p1.v;
    r.B[k] = p1.u - p0.u;
    r.C[k] = p0.u * p1.v - p1.u * p0.v;
    tol = std::max(
        tol, std::fabs(r.A[k]) * umax_ + std::fabs(r.B[k]) * vmax_ + std::fabs(p0.u * p1.v) + std::fabs(p1.u * p0.v));
  }
  r.tol = 16.0 * kUnitRoundoff * tol;
  r.u0 = corners2_[corner[0]].u, r.v0 = corners2_[corner[0]].v, r.h0 = cornerH_[corner[0]];
}

// The plane's slopes and the height range: two divisions, kept per triangle on a compact grid.
void PlanarCore::planeRecord(const std::uint32_t corner[3], Tri& r) const {
  double u[3], v[3], h[3];
  for (int k = 0; k < 3; ++k) {
    u[k] = corners2_[corner[k]].u, v[k] = corners2_[corner[k]].v, h[k] = cornerH_[corner[k]];
  }
  const PlaneFit p = fitPlane(u, v, h);
  r.a = p.a, r.b = p.b, r.h0 = p.h0;
  r.hlo = floatBelow(std::min(h[0], std::min(h[1], h[2])));
  r.hhi = floatAbove(std::max(h[0], std::max(h[1], h[2])));
}

// A triangle is referenced from a leaf when its closed projection meets the closed leaf box
// (separating axes: the box axes, then each edge with its error bound, so that a triangle is
// dropped only when the box is certainly outside it).
bool PlanarCore::overlaps(std::uint32_t t, const Box2& tb, const Box2& b) const {
  const Tri& r = tris_[t];
  if (tb.ulo > b.uhi || tb.uhi < b.ulo || tb.vlo > b.vhi || tb.vhi < b.vlo) return false;
  for (int k = 0; k < 3; ++k) {
    const double u = r.A[k] >= 0 ? b.uhi : b.ulo;
    const double v = r.B[k] >= 0 ? b.vhi : b.vlo;
    if (r.A[k] * u + r.B[k] * v + r.C[k] < -r.tol) return false;
  }
  return true;
}

Box2 PlanarCore::boxOf(std::uint32_t t) const {
  Box2 bb{INFINITY, INFINITY, -INFINITY, -INFINITY};
  for (std::uint32_t c : cold_[t].corner) {
    bb.ulo = std::min(bb.ulo, corners2_[c].u), bb.uhi = std::max(bb.uhi, corners2_[c].u);
    bb.vlo = std::min(bb.vlo, corners2_[c].v), bb.vhi = std::max(bb.vhi, corners2_[c].v);
  }
  return bb;
}

// Single-layer leaves: where no two of a leaf's triangles overlap, the first one containing a
// point is the only surface there, and the query stops at it. Their items are put in polygon
// order so that this first one is also the smallest polygon id, as the tie rule says.
bool PlanarCore::prepareLeaf(std::span<std::uint32_t> items) const {
  // The pairwise check is quadratic: a leaf this large (a large Maxpoly, or a stack no cut can
  // part) is simply not marked, which only costs the early exit.
  if (items.size() > 64) return false;
  for (std::size_t i = 0; i < items.size(); ++i) {
    for (std::size_t j = i + 1; j < items.size(); ++j) {
      if (!separated(items[i], items[j])) return false;
    }
  }
  std::sort(items.begin(), items.end(), [this](std::uint32_t a, std::uint32_t b) {
    return cold_[a].polygon != cold_[b].polygon ? cold_[a].polygon < cold_[b].polygon : a < b;
  });
  return true;
}

void PlanarCore::setTreeFloor(const std::vector<Box2>& boxes) const {
  // The size floor of the tree: half the median triangle extent along each axis. Smaller nodes
  // cannot part triangles that are larger than they are (a stack of surfaces seen along a
  // grazing light, a fan), they only multiply references.
  floorU_ = floorV_ = 0;
  if (boxes.empty()) return;
  std::vector<double> du(boxes.size()), dv(boxes.size());
  for (std::size_t t = 0; t < boxes.size(); ++t) {
    du[t] = boxes[t].uhi - boxes[t].ulo;
    dv[t] = boxes[t].vhi - boxes[t].vlo;
  }
  std::nth_element(du.begin(), du.begin() + du.size() / 2, du.end());
  std::nth_element(dv.begin(), dv.begin() + dv.size() / 2, dv.end());
  floorU_ = 0.5 * du[du.size() / 2];
  floorV_ = 0.5 * dv[dv.size() / 2];
}

void PlanarCore::buildDeferredTree() const {
  if (tris_.size() != cold_.size()) {
    tris_.resize(cold_.size());
    for (std::uint32_t t = 0; t < cold_.size(); ++t) tris_[t] = computeRecord(cold_[t].corner);
  }
  {
    std::vector<Box2> boxes(cold_.size());
    for (std::uint32_t t = 0; t < cold_.size(); ++t) boxes[t] = boxOf(t);
    setTreeFloor(boxes);
  }
  tree_.build(
      static_cast<std::uint32_t>(cold_.size()), stats_.domain, deferredOptions_,
      [this](std::uint32_t t, const Box2& b) {
        return !(cold_[t].polygon < removed_.size() && removed_[cold_[t].polygon]) && overlaps(t, boxOf(t), b);
      },
      floorU_, floorV_, [this](std::uint32_t t) { return boxOf(t); });
  tree_.markLeaves([this](std::span<std::uint32_t> items) { return prepareLeaf(items); });
  treeStatsStale_ = true;
  deferred_->built = true;
}

bool PlanarCore::separated(std::uint32_t a, std::uint32_t b) const {
  // Two counter-clockwise triangles have disjoint interiors exactly when an edge line of one has
  // all corners of the other on its outer side or on it (separating axis theorem). The edge
  // equations decide unless a corner is within their error bound of the line; then the exact
  // predicate does.
  const auto apart = [this](std::uint32_t p, std::uint32_t q) {
    const Tri& r = tris_[p];
    const Cold& cp = cold_[p];
    const Cold& cq = cold_[q];
    for (int k = 0; k < 3; ++k) {
      bool all = true;
      for (int c = 0; c < 3 && all; ++c) {
        // A corner shared with the edge lies on it: the common case of neighbours, no test.
        if (cq.corner[c] == cp.corner[k] || cq.corner[c] == cp.corner[(k + 1) % 3]) continue;
        const Point2 x = corners2_[cq.corner[c]];
        const double e = r.A[k] * x.u + r.B[k] * x.v + r.C[k];
        if (e > r.tol) {
          all = false;
        } else if (e >= -r.tol) {
          all = orient2dSign(corners2_[cp.corner[k]], corners2_[cp.corner[(k + 1) % 3]], x) <= 0;
        }
      }
      if (all) return true;
    }
    return false;
  };
  return apart(a, b) || apart(b, a);
}

bool PlanarCore::inside(std::uint32_t t, double u, double v) const {
  const Cold& c = cold_[t];
  const Point2 p{u, v};
  for (int k = 0; k < 3; ++k) {
    if (orient2dSign(corners2_[c.corner[k]], corners2_[c.corner[(k + 1) % 3]], p) < 0) return false;
  }
  return true;
}

inline double PlanarCore::heightOf(const Tri& t, double u, double v) const {
  // The clamp keeps a sliver's extrapolated plane inside its corners' height range.
  return std::clamp(t.h0 + t.a * (u - t.u0) + t.b * (v - t.v0), static_cast<double>(t.hlo), static_cast<double>(t.hhi));
}

// The nearest triangle at (u, v) on one side of z: Below = true finds the highest with h <= z,
// false the lowest with h >= z; equal heights go to the smaller polygon id.
//
// This is the hot loop. The leaf's triangle records are prefetched first, so their cache misses
// overlap instead of waiting on each other behind mispredicted branches; the per-triangle test
// then selects without branching on the data, except for the rare point within rounding of an
// edge, which takes the exact predicate.
template <bool Below>
std::uint32_t PlanarCore::nearest(double u, double v, double z, double& h, Quadtree::Cursor* cursor) const {
  if (grid_.on()) {
    const std::uint32_t t = gridAnswer<true>(u, v, h, cursor);
    if (t == kOffGrid) return kNone;
    return (Below ? h <= z : h >= z) ? t : kNone;
  }
  ensureTree();
  if (!tree_.contains(u, v)) return kNone;  // also rejects NaN
  const Quadtree::Node leaf = cursor ? tree_.leafNode(u, v, *cursor) : tree_.leafNode(u, v);
  const auto items = tree_.leafRange(leaf);
  prefetchTriangles(items);
  return nearestIn<Below>(items, Quadtree::singleLayer(leaf), u, v, z, h);
}

void PlanarCore::prefetchTriangles(std::span<const std::uint32_t> items) const {
  for (std::uint32_t t : items) {
    const char* p = reinterpret_cast<const char*>(&tris_[t]);
    __builtin_prefetch(p);
    __builtin_prefetch(p + 64);
  }
}

bool PlanarCore::contains(const Tri& r, std::uint32_t t, double u, double v) const {
  const double e0 = r.A[0] * u + r.B[0] * v + r.C[0];
  const double e1 = r.A[1] * u + r.B[1] * v + r.C[1];
  const double e2 = r.A[2] * u + r.B[2] * v + r.C[2];
  const double m = std::min(e0, std::min(e1, e2));
  if (std::fabs(m) <= r.tol) [[unlikely]]
    return inside(t, u, v);
  return m > 0;
}

template <bool Below>
std::uint32_t PlanarCore::nearestIn(std::span<const std::uint32_t> items, bool singleLayer, double u, double v,
                                    double z, double& h) const {
  if (singleLayer) {
    // One surface: the first triangle containing the point is the answer, if on the right side.
    for (std::uint32_t t : items) {
      const Tri& r = tris_[t];
      if (!contains(r, t, u, v)) continue;
      h = heightOf(r, u, v);
      return (Below ? h <= z : h >= z) ? t : kNone;
    }
    return kNone;
  }
  std::uint32_t found = kNone;
  double best = Below ? -std::numeric_limits<double>::infinity() : std::numeric_limits<double>::infinity();
  for (std::uint32_t t : items) {
    const Tri& r = tris_[t];
    const double e0 = r.A[0] * u + r.B[0] * v + r.C[0];
    const double e1 = r.A[1] * u + r.B[1] * v + r.C[1];
    const double e2 = r.A[2] * u + r.B[2] * v + r.C[2];
    const double m = std::min(e0, std::min(e1, e2));
    // Inside when the smallest edge value is positive; only within rounding of an edge (|m| at
    // most the error bound, which is rare and so well predicted) is the exact test needed.
    bool in = m > 0;
    if (std::fabs(m) <= r.tol) [[unlikely]] {
      in = inside(t, u, v);
    }
    const double ht = heightOf(r, u, v);
    const bool side = Below ? ht <= z : ht >= z;
    bool better = Below ? ht > best : ht < best;
    if (ht == best) [[unlikely]] {
      better = found != kNone && cold_[t].polygon < cold_[found].polygon;
    }
    // Bitwise, not short-circuit: a select, not three data-dependent branches.
    const bool take = in & side & better;
    found = take ? t : found;
    best = take ? ht : best;
  }
  h = best;
  return found;
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
std::optional<Hit> PlanarCore::hitAt(double u, double v, double z, Quadtree::Cursor* cursor) const {
  double h = 0;
  const std::uint32_t t = nearest<Below>(u, v, z, h, cursor);
  if (t == kNone) return std::nullopt;
  return makeHit(t, u, v, h);
}

std::optional<Hit> PlanarCore::below(double u, double v, double z) const { return hitAt<true>(u, v, z, nullptr); }

std::optional<Hit> PlanarCore::above(double u, double v, double z) const { return hitAt<false>(u, v, z, nullptr); }

namespace {

// One group of up to kLanes points on a lean grid: first every point's cell and the cache lines
// of its corners, then the planes and heights in SIMD. ok[i]: points[i] lies clearly inside a
// present triangle and h[i] is its height there; else the exact path must answer it (near a
// side, off the grid, in a hole, or a plane that needs fitPlane's checks or the clamp). hole[i]:
// it lies clearly inside a slot without a triangle, where the exact path finds none (its cell
// alone is tested, and the cell's other half cannot hold it). Unused lanes, and lanes without a
// triangle, compute on the corners of cell 0 and are thrown away.
// The cache lines a lean answer at cell c reads.
[[gnu::always_inline]] inline void prefetchLean(const detail::GridPath& grid, std::span<const Point2> corners,
                                                std::span<const double> heights, const detail::GridPath::Cell& c) {
  const std::uint64_t x = c.row * grid.w + c.col;
  if (!grid.presentBits.empty()) __builtin_prefetch(&grid.presentBits[c.slot >> 6]);
  if (!grid.h32.empty()) {
    __builtin_prefetch(&grid.h32[x]), __builtin_prefetch(&grid.h32[x + 1]);
    __builtin_prefetch(&grid.h32[x + grid.w]), __builtin_prefetch(&grid.h32[x + grid.w + 1]);
  } else {
    __builtin_prefetch(&heights[x]), __builtin_prefetch(&heights[x + 1]);
    __builtin_prefetch(&heights[x + grid.w]), __builtin_prefetch(&heights[x + grid.w + 1]);
  }
  if (grid.colU.empty()) __builtin_prefetch(&corners[x]), __builtin_prefetch(&corners[x + grid.w + 1]);
}

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
    prefetchLean(grid, corners, heights, c);
  }
  for (std::size_t i = 0; i < aheadN; ++i) {
    const detail::GridPath::Cell c = grid.cell(ahead[i].u, ahead[i].v);
    if (c.inGrid) prefetchLean(grid, corners, heights, c);
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
    if (!lean) {
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
  // Software pipelining over groups of points: first every point's leaf (the jump table), then
  // every leaf's reference list, then every leaf's triangles, each stage issuing its loads for
  // the whole group before any of them is waited for. A single query waits for three dependent
  // cache misses in turn; here the misses of a group overlap.
  constexpr std::size_t kGroup = 16;
  Quadtree::Node leaf[kGroup];
  bool on[kGroup];
  if (grid_.lean) {
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
        if (!ok[i] && gridAnswer<false>(points[g + i].u, points[g + i].v, h) == kOffGrid) {
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
        __builtin_prefetch(&grid_.cellTri[2 * (c.row * (grid_.w - 1) + c.col)]);
      }
      for (std::size_t i = 0; i < n; ++i) {
        if (!inGrid[i]) continue;
        const std::uint64_t first = cellSlot[i] - cellHalf[i];  // the cell's two halves
        for (int half = 0; half < 2; ++half) {
          const std::uint32_t t = grid_.cellTri[first + half];
          if (t == kNone) continue;
          __builtin_prefetch(&tris_[t]);
          __builtin_prefetch(reinterpret_cast<const char*>(&tris_[t]) + 64);
        }
      }
      for (std::size_t i = 0; i < n; ++i) {
        const Point2 p = points[g + i];
        double h = 0;
        heights[g + i] =
            gridAnswer<false>(p.u, p.v, h) != kOffGrid && h <= zOf(g + i) ? std::optional<double>(h) : std::nullopt;
      }
    }
    return;
  }
  for (std::size_t g = 0; g < points.size(); g += kGroup) {
    const std::size_t n = std::min(kGroup, points.size() - g);
    for (std::size_t i = 0; i < n; ++i) {
      const Point2 p = points[g + i];
      on[i] = tree_.contains(p.u, p.v);
      leaf[i] = on[i] ? tree_.leafNode(p.u, p.v) : Quadtree::Node{0, 0};
      __builtin_prefetch(tree_.leafRange(leaf[i]).data());
    }
    for (std::size_t i = 0; i < n; ++i) prefetchTriangles(tree_.leafRange(leaf[i]));
    for (std::size_t i = 0; i < n; ++i) {
      double h = 0;
      const Point2 p = points[g + i];
      const std::uint32_t t =
          on[i] ? nearestIn<true>(tree_.leafRange(leaf[i]), Quadtree::singleLayer(leaf[i]), p.u, p.v, zOf(g + i), h)
                : kNone;
      heights[g + i] = t == kNone ? std::nullopt : std::optional<double>(h);
    }
  }
}

void PlanarCore::heightsBelow(std::span<const Point2> points, double z,
                              std::span<std::optional<double>> heights) const {
  batch::requireRoom("heightsBelow", points.size(), heights.size());
  heightsBelowBatch(
      points, [z](std::size_t) { return z; }, heights);
}

void PlanarCore::heightsBelow(std::span<const Point2> points, std::span<const double> zs,
                              std::span<std::optional<double>> heights) const {
  batch::requireRoom("heightsBelow", points.size(), std::min(heights.size(), zs.size()));
  heightsBelowBatch(
      points, [zs](std::size_t i) { return zs[i]; }, heights);
}

void PlanarCore::heights(std::span<const Point2> points, std::span<std::optional<double>> heights) const {
  heightsBelow(points, kInf, heights);
}

void PlanarCore::heightsBelowParallel(std::span<const Point2> points, double z,
                                      std::span<std::optional<double>> heights, unsigned threads) const {
  batch::requireRoom("heightsBelowParallel", points.size(), heights.size());
  // The tree built once here, not raced for by the workers; the grid fast path never needs it
  // (off the grid and in holes it answers no terrain itself).
  if (!grid_.on()) ensureTree();
  batch::inSlices(points.size(), threads, 4096, [&](std::size_t lo, std::size_t hi) {
    heightsBelowBatch(
        points.subspan(lo, hi - lo), [z](std::size_t) { return z; }, heights.subspan(lo, hi - lo));
  });
}

void PlanarCore::heightsBelowParallel(std::span<const Point2> points, std::span<const double> zs,
                                      std::span<std::optional<double>> heights, unsigned threads) const {
  batch::requireRoom("heightsBelowParallel", points.size(), std::min(heights.size(), zs.size()));
  if (!grid_.on()) ensureTree();  // (as above)
  batch::inSlices(points.size(), threads, 4096, [&](std::size_t lo, std::size_t hi) {
    const std::span<const double> z = zs.subspan(lo, hi - lo);
    heightsBelowBatch(
        points.subspan(lo, hi - lo), [z](std::size_t i) { return z[i]; }, heights.subspan(lo, hi - lo));
  });
}

void PlanarCore::heightsParallel(std::span<const Point2> points, std::span<std::optional<double>> heights,
                                 unsigned threads) const {
  heightsBelowParallel(points, kInf, heights, threads);
}

double PlanarCore::heightAt(double u, double v, double z, Quadtree::Cursor* cursor) const {
  if (!grid_.on()) return heightFromTree(u, v, z, cursor);
  double h = 0;  // no need for the triangle's id
  if (gridAnswer<false>(u, v, h, cursor) == kOffGrid || !(h <= z)) return NAN;
  return h;
}

[[gnu::noinline]] double PlanarCore::heightFromTree(double u, double v, double z, Quadtree::Cursor* cursor) const {
  double h = 0;
  if (nearest<true>(u, v, z, h, cursor) == kNone) return NAN;
  return h;
}

std::optional<Hit> PlanarCore::below(Quadtree::Cursor& cursor, double u, double v, double z) const {
  return hitAt<true>(u, v, z, &cursor);
}

std::optional<Hit> PlanarCore::above(Quadtree::Cursor& cursor, double u, double v, double z) const {
  return hitAt<false>(u, v, z, &cursor);
}

Bracket PlanarCore::bracket(double u, double v, double h) const { return {below(u, v, h), above(u, v, h)}; }

std::optional<Hit> PlanarCore::top(double u, double v) const {
  return below(u, v, std::numeric_limits<double>::infinity());
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

std::optional<Hit> PlanarCore::belowWorld(const Eigen::Vector3d& p) const {
  const Eigen::Vector3d m = frame_.toMapped(p);
  return below(m.x(), m.y(), m.z());
}
std::optional<Hit> PlanarCore::aboveWorld(const Eigen::Vector3d& p) const {
  const Eigen::Vector3d m = frame_.toMapped(p);
  return above(m.x(), m.y(), m.z());
}
Bracket PlanarCore::bracketWorld(const Eigen::Vector3d& p) const {
  const Eigen::Vector3d m = frame_.toMapped(p);
  return bracket(m.x(), m.y(), m.z());
}
std::optional<Hit> PlanarCore::topWorld(const Eigen::Vector3d& p) const {
  const Eigen::Vector3d m = frame_.toMapped(p);
  return top(m.x(), m.y());
}
std::vector<Hit> PlanarCore::allWorld(const Eigen::Vector3d& p) const {
  const Eigen::Vector3d m = frame_.toMapped(p);
  return all(m.x(), m.y());
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
  if (c.polygon < removed_.size() && removed_[c.polygon]) return false;
  Tri scratch;
  const Tri& r = grid_.lean ? (scratch = computeRecord(c.corner)) : tris_[t];
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
  const PlaneFit f = fitPlane(p0.u, p0.v, c0.z(), p1.u, p1.v, h1, p2.u, p2.v, h2);
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

namespace qota {

std::vector<LineHit> PlanarCore::alongLine(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction, double tmin,
                                           double tmax) const {
  ensureTree();
  std::vector<LineHit> out;
  if (!origin.allFinite() || !direction.allFinite() || direction.squaredNorm() == 0) return out;  // no line
  // The line in the mapped frame: O + t d.
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
  const double dv[3] = {dn.x(), dn.y(), dn.z()};
  for (std::uint32_t t : candidates) {
    const Cold& c = cold_[t];
    // Exact side of the line against each edge: the sign of det[a - O; b - O; d] on the corners'
    // rounded offsets from O, the same for every triangle sharing the corner, so neighbours agree
    // on a shared edge and the line cannot slip between them.
    double q[3][3];
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t v = c.corner[k];
      q[k][0] = corners2_[v].u - O.x(), q[k][1] = corners2_[v].v - O.y(), q[k][2] = cornerH_[v] - O.z();
    }
    const int s0 = orient3dSign(q[0], q[1], dv), s1 = orient3dSign(q[1], q[2], dv), s2 = orient3dSign(q[2], q[0], dv);
    const bool neg = s0 < 0 || s1 < 0 || s2<0, pos = s0> 0 || s1 > 0 || s2 > 0;
    if (neg == pos) continue;  // outside, or the line lies in the triangle's plane
    const Eigen::Vector3d a(q[0][0], q[0][1], q[0][2]), b(q[1][0], q[1][1], q[1][2]), e(q[2][0], q[2][1], q[2][2]);
    Eigen::Vector3d n = (b - a).cross(e - a);
    const double nd = n.dot(dn);
    if (nd == 0) continue;
    const double tt = n.dot(a) / nd;
    if (tt < tmin || tt > tmax) continue;
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

}  // namespace qota

namespace qota {

void PlanarCore::rebuildTree(const Box2& domain) {
  // The edge tolerances hold for points within the domain: recompute them for the new one.
  umax_ = std::max(std::fabs(domain.ulo), std::fabs(domain.uhi));
  vmax_ = std::max(std::fabs(domain.vlo), std::fabs(domain.vhi));
  std::vector<Box2> boxes(tris_.size());
  for (std::uint32_t t = 0; t < tris_.size(); ++t) {
    const Cold c = cold_[t];
    boxes[t] = makeRecord(t, Pending{{c.corner[0], c.corner[1], c.corner[2]}, c.polygon});
  }
  const QuadtreeOptions options = tree_.options();
  const double minU = tree_.minSizeU(), minV = tree_.minSizeV();
  tree_.build(
      static_cast<std::uint32_t>(tris_.size()), domain, options,
      [this, &boxes](std::uint32_t t, const Box2& b) {
        return !(cold_[t].polygon < removed_.size() && removed_[cold_[t].polygon]) && overlaps(t, boxes[t], b);
      },
      minU, minV, [&boxes](std::uint32_t t) { return boxes[t]; });
  tree_.markLeaves([this](std::span<std::uint32_t> items) { return prepareLeaf(items); });
  stats_.domain = domain;
}

std::uint32_t PlanarCore::insertPolygon(std::span<const Eigen::Vector3d> corners) {
  ensureTree();
  ++generation_;
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
      throw Error("insertPolygon: corner " + describePoint(c) + " is not finite");
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
    if (!trianglesOf_.empty()) trianglesOf_.emplace(id, t);
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
  ++generation_;
  if (polygon >= stats_.polygons) return false;
  if (removed_.size() < stats_.polygons) removed_.resize(stats_.polygons, 0);
  if (removed_[polygon]) return false;
  if (trianglesOf_.empty()) {
    trianglesOf_.reserve(cold_.size());
    for (std::uint32_t t = 0; t < cold_.size(); ++t) trianglesOf_.emplace(cold_[t].polygon, t);
  }
  removed_[polygon] = 1;
  const auto [first, last] = trianglesOf_.equal_range(polygon);
  for (auto it = first; it != last; ++it) {
    tree_.remove(it->second, [this](std::uint32_t i, const Box2& b) { return overlaps(i, boxOf(i), b); });
    --stats_.triangles;
    if (grid_.on()) grid_.clearSlot(cold_[it->second], it->second);
  }
  if (first == last) --stats_.leftOut;
  trianglesOf_.erase(polygon);
  treeStatsStale_ = true;
  return true;
}

}  // namespace qota
