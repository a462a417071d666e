// Building the planar index (terrain.hpp): the mapped vertices, each polygon checked and fanned
// into triangles, the triangles ordered along a Morton curve, their records, the grid path
// recognised, and the quadtree (at once, or on first need over a grid).
#include "qota/terrain.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <future>
#include <limits>
#include <numeric>
#include <string>
#include <thread>
#include <utility>

#include "float_bounds.hpp"
#include "planar_answers.hpp"
#include "planar_arith.hpp"
#include "qota/batch.hpp"
#include "qota/error.hpp"
#include "qota/index.hpp"
#include "qota/memory_budget.hpp"

namespace qota {

namespace {

std::uint32_t spreadBits16(std::uint32_t x) {
  x &= 0xffff;
  x = (x | (x << 8)) & 0x00ff00ff;
  x = (x | (x << 4)) & 0x0f0f0f0f;
  x = (x | (x << 2)) & 0x33333333;
  x = (x | (x << 1)) & 0x55555555;
  return x;
}

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

// keyed (code << 32 | t, in increasing t) in increasing order: a stable sort by the code alone,
// in two passes of 16 bits, keeps equal codes in t's order, which is the order of the whole keys
// (std::sort's, at a fraction of its time on a million keys).
void sortByCode(std::vector<std::uint64_t>& keyed) {
  std::vector<std::uint64_t> other(keyed.size());
  std::vector<std::size_t> start(std::size_t{1} << 16);
  for (const int shift : {32, 48}) {
    std::fill(start.begin(), start.end(), 0);
    for (const std::uint64_t k : keyed) ++start[(k >> shift) & 0xffffu];
    std::size_t at = 0;
    for (std::size_t& s : start) at += std::exchange(s, at);
    for (const std::uint64_t k : keyed) other[start[(k >> shift) & 0xffffu]++] = k;
    keyed.swap(other);
  }
}

}  // namespace

static_assert(EditableTerrain<CartesianIndex>);  // (and every PlanarIndex<M>: the same core)

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
      add(tl, bl, br, RasterGrid::innerTriangle(w, r, c, 0));
      add(tl, br, tr, RasterGrid::innerTriangle(w, r, c, 1));
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
  std::atomic<bool> nonFinite{false};
  batch::inSlices(nv, options.buildThreads, 1u << 16, [&](std::size_t lo, std::size_t hi) {
    bool seen = false;
    for (std::size_t i = lo; i < hi; ++i) {
      const Eigen::Vector3d m = frame_.toMapped(vertices[i]);
      corners2_[i] = {m.x(), m.y()};
      cornerH_[i] = m.z();
      seen |= !(vertices[i].allFinite() && m.allFinite());
    }
    if (seen) nonFinite = true;
  });
  nonFiniteVertex_ = nonFinite;
}

void PlanarCore::checkCorners(std::span<const std::uint32_t> idx, std::size_t p,
                              std::span<const Eigen::Vector3d> vertices) const {
  const std::size_t nv = vertices.size();
  for (std::uint32_t i : idx) {
    if (i >= nv) {
      throw Error("polygon " + std::to_string(p) + " refers to vertex " + std::to_string(i) + " but the mesh has " +
                  std::to_string(nv) + " vertices");
    }
    // (Checked per corner only when the mapping pass saw a non-finite vertex: the corners are
    // in the mesh's order, and reading each vertex again is a cache miss per corner.)
    if (nonFiniteVertex_ && (!vertices[i].allFinite() || !std::isfinite(corners2_[i].u) ||
                             !std::isfinite(corners2_[i].v) || !std::isfinite(cornerH_[i]))) {
      throw Error("polygon " + std::to_string(p) + ": vertex " + std::to_string(i) + " has a non-finite coordinate " +
                  planar::describePoint(vertices[i]));
    }
  }
}

void PlanarCore::finishBuild(std::vector<Pending>& pending, const Lattice* lattice, const IndexOptions& options) {
  stats_.triangles = pending.size();

  // The domain: the bounding box of every triangle, in mapped coordinates.
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
    constexpr std::size_t kPerSlice = 1u << 15;
    const unsigned threads = options.buildThreads;
    const double su = domain.uhi > domain.ulo ? 65535.0 / (domain.uhi - domain.ulo) : 0.0;
    const double sv = domain.vhi > domain.vlo ? 65535.0 / (domain.vhi - domain.vlo) : 0.0;
    std::vector<std::uint64_t> keyed(pending.size());
    batch::inSlices(pending.size(), threads, kPerSlice, [&](std::size_t lo, std::size_t hi) {
      for (std::size_t t = lo; t < hi; ++t) {
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
    });
    // A raster's triangles usually come in row order already: then there is nothing to move.
    if (!std::is_sorted(keyed.begin(), keyed.end())) {
      sortByCode(keyed);
      std::vector<Pending> sorted(pending.size());
      batch::inSlices(keyed.size(), threads, kPerSlice, [&](std::size_t lo, std::size_t hi) {
        for (std::size_t t = lo; t < hi; ++t) sorted[t] = pending[keyed[t] & 0xffffffffu];
      });
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
  if (!grid_.isLean()) {
    tris_.resize(pending.size());
    batch::inSlices(pending.size(), options.buildThreads, 1u << 15, [&](std::size_t lo, std::size_t hi) {
      for (std::size_t t = lo; t < hi; ++t) {
        const Box2 box = makeRecord(static_cast<std::uint32_t>(t), pending[t]);
        if (!deferred) boxes[t] = box;
      }
    });
  }
  deferredOptions_ = options.tree;
  buildThreads_ = options.buildThreads;
  baseMemoryBytes_ =
      cold_.size() * sizeof(Cold) + corners2_.size() * (sizeof(Point2) + sizeof(double)) + grid_.memoryBytes();
  if (deferred) {
    // The grid answers every height query: the tree waits until something needs it.
    deferredTree_ = true;
    recordBytesBeforeTree_ = tris_.size() * sizeof(Tri);
    stats_.memoryBytes = baseMemoryBytes_ + recordBytesBeforeTree_;
  } else {
    setTreeFloor(boxes);
    buildTreeOver(boxes, domain, options.tree, floorU_, floorV_, options.buildThreads);
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

// The hot and cold records of triangle t. Returns the triangle's bounding box.
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

// Corner 0 and the other two relative to it, rounded to float; NaN offsets, all four, where one is
// not a normal float or zero (tiny or huge triangles: their tests all go to the exact predicate).
// Cheap: recomputed per query on a compact grid.
void PlanarCore::edgeRecord(const std::uint32_t corner[3], Tri& r) const {
  const Point2 p0 = corners2_[corner[0]], p1 = corners2_[corner[1]], p2 = corners2_[corner[2]];
  r.u0 = p0.u, r.v0 = p0.v, r.h0 = cornerH_[corner[0]];
  const double offsets[4] = {p1.u - p0.u, p1.v - p0.v, p2.u - p0.u, p2.v - p0.v};
  float* out[4] = {&r.du1, &r.dv1, &r.du2, &r.dv2};
  // Checked before the conversion (a double beyond float's range does not convert); at most
  // 2^100 keeps the bound's products finite.
  bool normal = true;
  for (const double d : offsets) normal &= d == 0 || (std::fabs(d) >= 0x1p-126 && std::fabs(d) <= 0x1p100);
  for (int k = 0; k < 4; ++k) {
    *out[k] = normal ? static_cast<float>(offsets[k]) : std::numeric_limits<float>::quiet_NaN();
  }
}

// The plane's slopes and the height range: two divisions, kept per triangle unless the grid is lean.
void PlanarCore::planeRecord(const std::uint32_t corner[3], Tri& r) const {
  double u[3], v[3], h[3];
  for (int k = 0; k < 3; ++k) {
    u[k] = corners2_[corner[k]].u, v[k] = corners2_[corner[k]].v, h[k] = cornerH_[corner[k]];
  }
  const planar::PlaneFit p = planar::cornerPlane(u, v, h);
  r.a = p.a, r.b = p.b, r.h0 = p.h0;
  r.hlo = floatBelow(std::min(h[0], std::min(h[1], h[2])));
  r.hhi = floatAbove(std::max(h[0], std::max(h[1], h[2])));
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
  if (items.size() > kMaxCheckedLeaf) return false;
  // Each triangle's edges and corners gathered once, on first need: the pairs then test from the
  // stack instead of reloading two records a pair (a leaf of n triangles has n (n - 1) / 2
  // pairs: 14 million for a TIN of a million triangles, a third of its build before this).
  EdgeView view[kMaxCheckedLeaf];
  std::uint64_t gathered = 0;  // bit i: view[i] is filled
  auto viewOf = [&](std::size_t i) -> const EdgeView& {
    if (!(gathered >> i & 1u)) view[i] = edgeView(items[i]), gathered |= std::uint64_t{1} << i;
    return view[i];
  };
  // Neighbouring leaves share triangles, so a pair found apart is remembered in a small
  // direct-mapped table (per thread, for this index: a triangle's record never changes): about
  // two pairs in five are then a lookup.
  struct Remembered {
    const PlanarCore* owner = nullptr;
    std::uint64_t serial = 0;
    std::uint64_t pair[4096] = {};
  };
  thread_local Remembered apart;
  if (apart.owner != this || apart.serial != serial_) {
    apart.owner = this, apart.serial = serial_;
    std::fill(std::begin(apart.pair), std::end(apart.pair), ~std::uint64_t{0});
  }
  for (std::size_t i = 0; i < items.size(); ++i) {
    for (std::size_t j = i + 1; j < items.size(); ++j) {
      const std::uint64_t key = std::uint64_t{std::min(items[i], items[j])} << 32 | std::max(items[i], items[j]);
      std::uint64_t& slot = apart.pair[(key * 0x9e3779b97f4a7c15ull) >> 52];
      if (slot == key) continue;
      if (!separated(viewOf(i), viewOf(j))) return false;
      slot = key;
    }
  }
  return orderLeaf(items);
}

bool PlanarCore::orderLeaf(std::span<std::uint32_t> items) const {
  if (items.size() > kMaxCheckedLeaf) return false;  // (as prepareLeaf leaves it: the same index)
  // By (polygon, triangle), each key read once; an insertion sort, as leaves are a few items.
  std::uint64_t key[kMaxCheckedLeaf];
  for (std::size_t i = 0; i < items.size(); ++i) {
    const std::uint64_t k = std::uint64_t{cold_[items[i]].polygon} << 32 | items[i];
    std::size_t j = i;
    for (; j > 0 && key[j - 1] > k; --j) key[j] = key[j - 1];
    key[j] = k;
  }
  for (std::size_t i = 0; i < items.size(); ++i) items[i] = static_cast<std::uint32_t>(key[i]);
  return true;
}

// The edge equations A u + B v + C in absolute coordinates, with one error bound for every (u, v)
// in the domain: the rounded A, B, C (one rounding each, two for C's products) and the evaluation
// (three roundings) stay within 8 units of the magnitude sum; 16 leaves a margin.
PlanarCore::EdgeView PlanarCore::edgeView(std::uint32_t t) const {
  EdgeView e;
  double tol = 0;
  for (int k = 0; k < 3; ++k) {
    e.corner[k] = cold_[t].corner[k];
    e.u[k] = corners2_[e.corner[k]].u, e.v[k] = corners2_[e.corner[k]].v;
  }
  for (int k = 0; k < 3; ++k) {
    const int k1 = k == 2 ? 0 : k + 1;
    e.A[k] = e.v[k] - e.v[k1];
    e.B[k] = e.u[k1] - e.u[k];
    e.C[k] = e.u[k] * e.v[k1] - e.u[k1] * e.v[k];
    tol = std::max(tol, std::fabs(e.A[k]) * umax_ + std::fabs(e.B[k]) * vmax_ + std::fabs(e.u[k] * e.v[k1]) +
                            std::fabs(e.u[k1] * e.v[k]));
  }
  e.tol = 16.0 * planar::kUnitRoundoff * tol;
  return e;
}

void PlanarCore::setTreeFloor(const std::vector<Box2>& boxes) const {
  // The size floor of the tree: half the median triangle extent along each axis. Smaller nodes
  // cannot part triangles that are larger than they are (a stack of surfaces seen along a
  // grazing light, a fan), they only multiply references.
  floorU_ = floorV_ = 0;
  if (boxes.empty()) return;
  // (Each axis on a thread of its own when the build has two.)
  std::vector<double> extent[2];
  batch::inSlices(2, buildThreads_, 1, [&](std::size_t lo, std::size_t hi) {
    for (std::size_t axis = lo; axis < hi; ++axis) {
      std::vector<double>& e = extent[axis];
      e.resize(boxes.size());
      for (std::size_t t = 0; t < boxes.size(); ++t) {
        e[t] = axis == 0 ? boxes[t].uhi - boxes[t].ulo : boxes[t].vhi - boxes[t].vlo;
      }
      std::nth_element(e.begin(), e.begin() + static_cast<std::ptrdiff_t>(e.size() / 2), e.end());
    }
  });
  floorU_ = 0.5 * extent[0][boxes.size() / 2];
  floorV_ = 0.5 * extent[1][boxes.size() / 2];
}

void PlanarCore::remakeRecords() const {
  tris_.resize(cold_.size());
  batch::inSlices(cold_.size(), buildThreads_, 1u << 15, [this](std::size_t lo, std::size_t hi) {
    for (std::size_t t = lo; t < hi; ++t) tris_[t] = computeRecord(cold_[t].corner);
  });
}

void PlanarCore::buildDeferredTree() const {
  if (tris_.size() != cold_.size()) remakeRecords();
  // The boxes once: the build tests each triangle against four children a level (1.6x faster
  // than computing them each time; 32 bytes a triangle while the tree is built, in
  // memory::kCartesianIndex).
  std::vector<Box2> boxes(cold_.size());
  batch::inSlices(cold_.size(), buildThreads_, 1u << 15, [&](std::size_t lo, std::size_t hi) {
    for (std::size_t t = lo; t < hi; ++t) boxes[t] = boxOf(static_cast<std::uint32_t>(t));
  });
  setTreeFloor(boxes);
  buildTreeOver(boxes, stats_.domain, deferredOptions_, floorU_, floorV_, buildThreads_);
  treeStatsStale_ = true;
  deferred_->built = true;
}

void PlanarCore::buildTreeOver(const std::vector<Box2>& boxes, const Box2& domain, const QuadtreeOptions& options,
                               double minU, double minV, unsigned threads) const {
  // (A fresh index has removed nothing: its build reads no triangle's polygon id, four times an
  // item a level.)
  const bool anyRemoved = ledger_.anyRemoved();
  // One sheet (a TIN, a grid seen from above) has every leaf a single layer, no pair to test;
  // the proof reads the edges alone, so it runs beside the tree's build when there are threads.
  std::future<bool> sheetBeside;
  if (threads != 1) sheetBeside = std::async(std::launch::async, [this] { return oneSheet(); });
  tree_.build(
      static_cast<std::uint32_t>(boxes.size()), domain, options,
      [this, &boxes, anyRemoved](std::uint32_t t, const Box2& b) {
        return !(anyRemoved && ledger_.removed(cold_[t].polygon)) && overlaps(t, boxes[t], b);
      },
      minU, minV, [&boxes](std::uint32_t t) { return boxes[t]; }, threads);
  const bool sheet = sheetBeside.valid() ? sheetBeside.get() : oneSheet();
  tree_.markLeaves(
      [this, sheet](std::span<std::uint32_t> items) { return sheet ? orderLeaf(items) : prepareLeaf(items); }, threads);
}

bool PlanarCore::separated(const EdgeView& a, const EdgeView& b) {
  // Two counter-clockwise triangles have disjoint interiors exactly when an edge line of one has
  // all corners of the other on its outer side or on it (separating axis theorem). The edge
  // equations decide unless a corner is within their error bound of the line; then the exact
  // predicate does (the rare slow path below).
  const auto exact = [](const EdgeView& p, const EdgeView& q) {
    for (int k = 0; k < 3; ++k) {
      const int k1 = k == 2 ? 0 : k + 1;
      bool all = true;
      for (int c = 0; c < 3 && all; ++c) {
        if (q.corner[c] == p.corner[k] || q.corner[c] == p.corner[k1]) continue;
        const Point2 x{q.u[c], q.v[c]};
        const double e = p.A[k] * x.u + p.B[k] * x.v + p.C[k];
        if (e > p.tol) {
          all = false;
        } else if (e >= -p.tol) {
          all = orient2dSign({p.u[k], p.v[k]}, {p.u[k1], p.v[k1]}, x) <= 0;
        }
      }
      if (all) return true;
    }
    return false;
  };
  // The same test without branching on the data: all nine evaluations, then the verdict. It
  // decides unless no edge is clearly separating and one is undecided (a corner within the
  // bound, none clearly inside): only then the exact loop runs. (The branching loop alone took
  // about 30 ns a pair on a TIN, where every pair is apart and all of them are tested.)
  const auto fast = [&exact](const EdgeView& p, const EdgeView& q) {
    bool separating = false, undecided = false;
    for (int k = 0; k < 3; ++k) {
      const int k1 = k == 2 ? 0 : k + 1;
      bool allOut = true, anyIn = false;
      for (int c = 0; c < 3; ++c) {
        // A corner shared with the edge lies on it: the common case of neighbours.
        const bool shared = (q.corner[c] == p.corner[k]) | (q.corner[c] == p.corner[k1]);
        const double e = p.A[k] * q.u[c] + p.B[k] * q.v[c] + p.C[k];
        allOut &= shared | (e < -p.tol);
        anyIn |= !shared & (e > p.tol);
      }
      separating |= allOut;
      undecided |= !allOut & !anyIn;
    }
    if (separating) return true;
    return undecided && exact(p, q);
  };
  return fast(a, b) || fast(b, a);
}

}  // namespace qota
