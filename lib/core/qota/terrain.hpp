// CartesianIndex (PlanarIndex<M>): the QOTA terrain query structure for a planar mapping: the
// Cartesian one with any gravity (MERL TR-96-17), or a local east-north-up frame.
//
// Build: every vertex is mapped once to (u, v, h) (so polygons sharing a vertex share its mapped
// coordinates bit for bit); every convex polygon is split into a fan of triangles in the mapped
// frame; triangles are stored once, in Morton order of their centroids, as packed 64-byte records
// (corner 0, the other two relative to it in float, whose edge tests carry an error bound, and the
// height plane solved from corner 0; no separate bbox: the three edge tests cost about what four
// bbox compares do) with their corners and source polygon kept apart; the quadtree references them
// from every leaf their projection meets. On a regular grid (a raster's triangles) the grid path finds the triangle
// under a point by arithmetic instead (grid_path.hpp), and the quadtree is built on first need.
//
// Query: descend to the leaf of (u, v) (two compares a level), then for each referenced
// triangle three edge checks and one plane solve; on the grid path, the cell and its half, then
// the plane of its three corners.
//
// Files: planar_build.cpp (the build), planar_query.cpp (single queries), planar_batch.cpp
// (batches), planar_lines.cpp (alongLine), planar_edits.cpp (edits); the plane arithmetic they
// share in planar_arith.hpp, the hot answers in planar_answers.hpp.
//
// Boundary rule (watertight): triangles are closed. A point is inside a triangle when the exact
// orientation of the point against each of its edges is >= 0. The edge equations are evaluated in
// floating point with a per-triangle error bound, and only points within that bound of an edge
// (points on an edge, in practice) go to the exact predicate (predicates.hpp). So a point on an
// edge or vertex shared by adjacent triangles hits every one of them, and the union of the closed
// triangles has no cracks: a query inside the terrain never falls through. A point in a hole hits
// nothing, and queries outside the bounding box of the terrain return "no terrain" at once.
//
// Polygon rules: 3 or more vertex indices, all in range, all finite (else qota::Error naming the
// polygon). Polygons are tested for convexity as seen along gravity, exactly; a non-convex one is
// an error naming it. A polygon whose projection has zero area (a vertical wall, or a degenerate
// one) is left out of the query structure and counted in IndexStats::leftOut. A polygon of more than 3
// vertices is fanned from its first vertex; each fan triangle carries its own plane, so a
// slightly non-planar polygon is followed exactly through its fan.
//
// Ties: when several polygons are equally near (a point on a shared edge), the one with the
// smallest polygon id is returned. Heights are "above" when h >= z and "below" when h <= z, so a
// hit exactly at the query height is both.
//
// Thread safety: a built index is immutable; any number of threads may query it at once.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <limits>
#include <atomic>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <unordered_map>
#include <vector>

#include "qota/cartesian.hpp"
#include "qota/enu.hpp"
#include "qota/grid_path.hpp"
#include "qota/index_face.hpp"
#include "qota/memory.hpp"
#include "qota/mesh.hpp"
#include "qota/planar.hpp"
#include "qota/polygon_ledger.hpp"
#include "qota/predicates.hpp"
#include "qota/quadtree.hpp"
#include "qota/vocabulary.hpp"

namespace qota {

// The planar index's work, written once over the frame of any planar mapping (planar.hpp);
// PlanarIndex<M> below adds the mapping itself.
class PlanarCore : public IndexFace<PlanarCore> {
 public:
  // Throws qota::Error for invalid polygons (see the rules above).
  PlanarCore(const Mesh& mesh, const PlanarFrame& frame, const IndexOptions& options = {});
  // The index of grid.toMesh(), bit for bit, built straight from the grid (no index list, and
  // no search for the grid in it).
  PlanarCore(const GridMesh& grid, const PlanarFrame& frame, const IndexOptions& options = {});

  // The face (index_face.hpp): below, above, bracket, top, height, heightBelow at mapped (u, v),
  // from a cursor, at a world point (the line through it along gravity, "below"
  // meaning further along gravity) and in batches; and here every polygon at (u, v), top to
  // bottom.
  std::vector<Hit> all(double u, double v) const;

  // Every crossing of an arbitrary world line origin + t * direction, t in [tmin, tmax], nearest
  // t first (equal t: smaller polygon id): for lines not along gravity, such as the world's
  // gravity seen from a part of a scene that tilts. The quadtree is walked along the line's
  // projection (only the piece inside the terrain's height range), and each candidate triangle
  // is tested exactly (orient3dSign on its corners' offsets from the line's origin), so the line
  // cannot slip between neighbours. Heights in the hits are this index's mapped h.
  std::vector<LineHit> alongLine(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                                 double tmin = -INFINITY, double tmax = INFINITY) const;

  // Whether the open segment from world point a to world point b meets terrain strictly between
  // its ends: crosses or touches a triangle (closed, by alongLine's exact side tests) at a line
  // parameter t with 0 < t < 1 (t computed in floating point, so ends that lie on terrain must be
  // named: see below). A triangle whose plane holds the segment is grazed, not met (its
  // neighbours decide, as alongLine). endVertex: b is this mesh vertex, so the triangles that
  // have it as a corner meet the segment only at b and are left out (kNoVertex: none). skip: polygons
  // left out as well (those a lies on), sorted. The walk skips every quadtree node the segment
  // passes above (each node keeps the greatest height of its triangles), and stops at the first
  // triangle met: a viewshed's line of sight, a point light's ray. Thread-safe with queries.
  static constexpr std::uint32_t kNoVertex = 0xffffffffu;
  bool segmentMeets(const Eigen::Vector3d& a, const Eigen::Vector3d& b, std::uint32_t endVertex = kNoVertex,
                    std::span<const std::uint32_t> skip = {}) const {
    return segmentMeetsWhich(a, b, endVertex, skip) != kNoPolygon;
  }
  // The same, naming the polygon of the triangle met (the first the walk finds), or kNoPolygon:
  // a neighbouring line of sight is often blocked by it too (viewshed.cpp tries it first).
  static constexpr std::uint32_t kNoPolygon = 0xffffffffu;
  std::uint32_t segmentMeetsWhich(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                  std::uint32_t endVertex = kNoVertex, std::span<const std::uint32_t> skip = {}) const;

  // Dynamic edits (the paper's dynamic insertion). insertPolygon adds a convex polygon given by
  // its world corners (at least 3, finite; the same rules as the mesh's polygons) and returns its
  // id, which continues after the mesh's (polygon ids are never reused). Its triangles go into
  // every leaf they meet, and leaves that then exceed Maxpoly split as the build would split
  // them; a polygon reaching outside the tree's box grows the box and rebuilds the tree (not
  // the triangle records). Corners equal to existing ones map to the same mapped coordinates, so
  // shared edges stay watertight. removePolygon takes a polygon (of the mesh or inserted) out of
  // every leaf; false when there is no such live polygon. After any sequence of edits every
  // query answers as an index built from scratch on the live polygons would (same heights, and
  // the same polygons under the id order). Not thread-safe against concurrent queries.
  std::uint32_t insertPolygon(std::span<const Eigen::Vector3d> corners);
  bool removePolygon(std::uint32_t polygon);

  // Whether a triangle that does not have mesh vertex `vertex` as a corner contains (u, v) at a
  // height strictly above h: the shadow test of a point at that vertex, whose own triangles can
  // never shade it (they meet its line at the point itself).
  bool occludedAbove(double u, double v, double h, std::uint32_t vertex) const;

  const PlanarFrame& frame() const { return frame_; }
  // True while the grid fast path is active (IndexOptions::gridFastPath, a regular grid, no
  // insertion since).
  bool gridFastPath() const { return grid_.on(); }
  // Thread-safe with queries and with itself (not with edits, which nothing is).
  const IndexStats& stats() const {
    ensureTree();
    const std::lock_guard<std::mutex> lock(deferred_->stats);
    if (treeStatsStale_) {  // after edits, the deferred build, or segmentMeets' node heights
      stats_.tree = tree_.stats();
      const bool tops = deferred_->topsFor.load(std::memory_order_acquire) == generation_ + 1;
      stats_.memoryBytes = baseMemoryBytes_ + tris_.size() * sizeof(Tri) + stats_.tree.memoryBytes +
                           (tops ? nodeTops_.size() * sizeof(float) : 0);
      treeStatsStale_ = false;
    }
    return stats_;
  }
  const Quadtree& tree() const {
    ensureTree();
    return tree_;
  }
  // The memory the index holds right now: without the tree (and the records it brings) while a
  // grid has not needed it. Thread-safe, during the deferred build too.
  std::uint64_t memoryBytesNow() const {
    return deferredTree_ && !deferred_->built.load() ? baseMemoryBytes_ + recordBytesBeforeTree_ : stats().memoryBytes;
  }

  // The memory a query at (u, v) looks at: polygon tests (bbox checks), the size of its leaf.
  std::uint32_t testsAt(double u, double v) const;

 protected:
  PlanarCore() = default;

 private:
  friend struct TreeFileAccess;                                            // the on-disk format (treefile.hpp)
  friend class IndexFace<PlanarCore>;                                      // the face's primitives:
  static constexpr double kTop = std::numeric_limits<double>::infinity();  // "below" any terrain
  std::optional<Hit> hitBelow(double u, double v, double h, Cursor* cursor) const;
  std::optional<Hit> hitAbove(double u, double v, double h, Cursor* cursor) const;
  std::optional<double> heightQuery(double u, double v, double z, Cursor* cursor) const {
    return unlessNaN(heightAt(u, v, z, cursor));
  }
  bool toQuery(const Eigen::Vector3d& world, Eigen::Vector3d& m) const {
    m = frame_.toMapped(world);
    return true;
  }
  void batchBelow(std::span<const Point2> points, double z, std::span<std::optional<double>> out) const;
  void batchBelow(std::span<const Point2> points, std::span<const double> zs,
                  std::span<std::optional<double>> out) const;
  // The tree built once before the slices run, not raced for by the workers; the grid fast
  // path never needs it (off the grid and in holes it answers no terrain itself).
  void beforeParallel() const {
    if (!grid_.on()) ensureTree();
  }
  template <class ZOf>  // z of point i: zOf(i)
  void heightsBelowBatch(std::span<const Point2> points, const ZOf& zOf, std::span<std::optional<double>> out) const;
  // Hot per-triangle record, one per triangle, 64 bytes (one cache line), in Morton order.
  // The plane is solved from corner 0 (h0 + a (u - u0) + b (v - v0)) rather than as a u + b v + c:
  // exact at that corner and with rounding proportional to the local relief, not to the size of
  // the coordinates. The edges are corners 1 and 2 relative to corner 0, rounded to float: the
  // edge tests (edgeTest) then work relative to corner 0 too, and their error bound, which covers
  // the float rounding, is computed from these numbers at the query (a few operations, cheaper
  // than the second cache line they would take to store). There is no separate bbox: the three
  // edge tests cost about as much as four bbox compares and need no extra bytes.
  struct alignas(64) Tri {
    double u0, v0, h0;  // corner 0
    double a, b;        // plane slopes: dh/du, dh/dv
    // Corners 1 and 2 less corner 0. All four NaN where one is not a normal float (or zero):
    // every test of that triangle is then exact.
    float du1, dv1;
    float du2, dv2;
    float hlo, hhi;  // height range of the corners, rounded outward (clamps the plane)
  };
  static_assert(sizeof(Tri) == 64);
  // The smallest of a triangle's three edge values at a point and the error bound of the three:
  // the point is inside beyond rounding when m > tol, outside when m < -tol; otherwise (or when
  // either is NaN) only the exact predicate decides.
  struct EdgeTest {
    double m, tol;
    bool undecided() const { return !(std::fabs(m) > tol); }
  };
  static EdgeTest edgeTest(const Tri& r, double u, double v);
  struct EdgeValues {  // the three edge values and their bound
    double e[3], tol;
  };
  static EdgeValues edgeValues(const Tri& r, double u, double v);
  static double offsetSum(const Tri& r);                    // s: the offsets' magnitudes summed
  static double edgeBound(double s, double du, double dv);  // the bound at (du, dv) from corner 0

  // Per triangle, its mapped vertex indices (counter-clockwise) and source polygon; the same
  // before it gets its records (Pending, a polygon's fan).
  using Cold = detail::TriangleCorners;
  using Pending = detail::TriangleCorners;
  void fanPolygon(std::span<const std::uint32_t> idx, std::uint32_t polygon, std::vector<Pending>& pending) const;
  // The build's steps: the size checks and the mapped vertices; a polygon's corners checked (in
  // range, finite); then everything after the fan. A grid mesh hands its lattice's shape and
  // each triangle's slot to the last.
  struct Lattice {
    std::uint64_t width, height;
    std::vector<std::uint32_t> slots;
  };
  void startBuild(std::span<const Eigen::Vector3d> vertices, std::uint64_t polygons, std::uint64_t fanned,
                  const IndexOptions& options);
  void checkCorners(std::span<const std::uint32_t> idx, std::size_t polygon,
                    std::span<const Eigen::Vector3d> vertices) const;
  bool nonFiniteVertex_ = false;  // startBuild saw a vertex, or its mapped point, not finite
  void finishBuild(std::vector<Pending>& pending, const Lattice* lattice, const IndexOptions& options);
  Box2 makeRecord(std::uint32_t t, const Pending& q);
  // A triangle is referenced from a leaf when its closed projection meets the closed leaf box
  // (separating axes: the box axes, then each edge with its error bound, so that a triangle is
  // dropped only when the box is certainly outside it). Inline: the build asks it four times
  // per triangle a level.
  bool overlaps(std::uint32_t t, const Box2& tb, const Box2& b) const {
    if (tb.ulo > b.uhi || tb.uhi < b.ulo || tb.vlo > b.vhi || tb.vhi < b.vlo) return false;
    // A triangle whose box lies in the box along either axis meets it: the box's band along
    // that axis crosses the triangle (most of a build's tests above the leaves' size).
    if ((tb.ulo >= b.ulo && tb.uhi <= b.uhi) || (tb.vlo >= b.vlo && tb.vhi <= b.vhi)) return true;
    return edgesReach(tris_[t], b);
  }
  // Whether the box may meet the triangle's edge half-planes: false only when one edge has the
  // whole box beyond its error bound outside.
  static bool edgesReach(const Tri& r, const Box2& b);
  Box2 boxOf(std::uint32_t t) const;
  // A leaf's single-layer test (pairwise), and its order when single-layer (by polygon id, so
  // that the first triangle holding a point answers). A leaf of more than kMaxCheckedLeaf items is
  // not marked: the pairs are quadratic.
  static constexpr std::size_t kMaxCheckedLeaf = 64;
  bool prepareLeaf(std::span<std::uint32_t> items) const;
  bool orderLeaf(std::span<std::uint32_t> items) const;
  // Whether the live triangles' interiors are pairwise disjoint, by the mesh's edges and
  // boundary alone (planar_sheet.cpp); false when that proof does not apply (then the pairs).
  bool oneSheet() const;

  // occludedAbove's test of one triangle t.
  bool triangleOccludesAbove(std::uint32_t t, double u, double v, double h, std::uint32_t vertex) const;
  bool inside(std::uint32_t t, double u, double v) const;
  double heightOf(const Tri& t, double u, double v) const;
  Hit makeHit(std::uint32_t t, double u, double v, double h) const;
  // below/above/heightBelow with or without a cursor.
  template <bool Below>
  std::optional<Hit> hitAt(double u, double v, double z, Cursor* cursor) const;
  // NaN for no terrain (a height is never NaN). heightBelow wraps it inline: an optional made
  // in the caller dissolves into its branch, one returned from a call goes through memory, where
  // its flag byte stalls the load of the whole (a store-forwarding failure, a third of a walk).
  double heightAt(double u, double v, double z, Cursor* cursor) const;
  double heightFromTree(double u, double v, double z, Cursor* cursor) const;
  static std::optional<double> unlessNaN(double h) {
    if (h != h) return std::nullopt;
    return h;
  }
  template <bool Below>
  std::uint32_t nearest(double u, double v, double z, double& h, Cursor* cursor = nullptr) const;
  template <bool Below>
  std::uint32_t nearestIn(std::span<const std::uint32_t> items, bool singleLayer, double u, double v, double z,
                          double& h) const;
  bool contains(const Tri& r, std::uint32_t t, double u, double v) const;
  // A triangle's edge equations (absolute: A u + B v + C, with their bound over the domain) and
  // corners, as the single-layer check reads them, made from its corners.
  // (Plain numbers, no initializers: prepareLeaf keeps 64 of them on its stack uninitialized.)
  struct EdgeView {
    std::uint32_t corner[3];
    double u[3], v[3];
    double A[3], B[3], C[3], tol;
  };
  EdgeView edgeView(std::uint32_t t) const;
  static bool separated(const EdgeView& a, const EdgeView& b);
  // This index's build among all in the process (prepareLeaf's table of pairs found apart).
  std::uint64_t serial_ = nextSerial();
  void prefetchTriangles(std::span<const std::uint32_t> items) const;

  PlanarFrame frame_;
  mutable BigVector<Tri> tris_;  // empty for a lean grid until the tree is built
  BigVector<Cold> cold_;
  BigVector<Point2> corners2_;                 // mapped (u, v) of each vertex, for the exact predicate
  BigVector<double> cornerH_;                  // mapped h of each vertex (for lines not along gravity)
  double hmin_ = INFINITY, hmax_ = -INFINITY;  // the triangles' height range
  double umax_ = 0, vmax_ = 0;                 // largest |u|, |v| of the domain: edgeView's bound
  PolygonLedger ledger_;                       // edits: the removed polygons, each polygon's triangles
  void rebuildTree(const Box2& domain);
  // The grid fast path (IndexOptions::gridFastPath, grid_path.hpp): where a point falls on a
  // regular grid and which triangle is there; the plane arithmetic below stays here.
  detail::GridPath grid_;
  // The triangle holding (u, v) by the grid's rule, with its record, or kNoTriangle for none (a
  // hole, off the grid).
  // `record` points at the stored record, or at `scratch` where it was computed.
  std::uint32_t gridTriangle(double u, double v, Tri& scratch, const Tri*& record) const;
  // Its rare path, kept out of line: points on or near an edge, in holes, off the grid.
  [[gnu::noinline]] std::uint32_t gridTriangleNearEdge(double u, double v, double fc, double fr, Tri& scratch,
                                                       const Tri*& record) const;
  // The record of triangle t of the grid: the stored one, or computed into scratch from its
  // corners while no records are kept.
  const Tri& gridRecord(std::uint32_t t, Tri& scratch) const;
  Tri recordOf(std::uint32_t t) const;  // stored, or computed from its corners
  Tri computeRecord(const std::uint32_t corner[3]) const;
  void remakeRecords() const;  // every triangle's record from its corners (cold_, on buildThreads_)
  void edgeRecord(const std::uint32_t corner[3], Tri& r) const;  // corner 0 and the offsets
  void planeRecord(const std::uint32_t corner[3], Tri& r) const;
  // The lean grid's answer at (u, v): the height, and the triangle (kNoTriangle: none; with
  // NeedId false, kFound stands for any triangle, whose id is not looked up).
  static constexpr std::uint32_t kFound = 0xfffffffdu;
  // Cursor::Memo::key of a quadtree walk's last triangle (a grid's memo keys are its slots).
  static constexpr std::uint64_t kTreeMemo = ~std::uint64_t{0} - 1;
  // A cursor remembers the last triangle's plane (Cursor::memo).
  template <bool NeedId>
  std::uint32_t gridAnswer(double u, double v, double& h, Cursor* cursor = nullptr) const;
  // Its answer near a triangle's side or off the lean grid (out of line: the hot path keeps a
  // small frame).
  std::uint32_t gridAnswerNearEdge(double u, double v, double fc, double fr, double& h) const;
  std::uint32_t gridAnswerFromRecords(double u, double v, double& h) const;  // grid not lean
  // The plane of the triangle in half `half` of cell (col, row), from its corners: slopes, the
  // height at corner 0 and corner 0, and the corners' height range.
  struct LeanPlane {
    double a, b, h0, u0, v0, lo, hi;
  };
  double leanAnswer(std::uint64_t col, std::uint64_t row, std::uint32_t half, double u, double v, LeanPlane& p) const;
  // Corner k of that triangle.
  void leanCorner(std::uint64_t col, std::uint64_t row, std::uint32_t half, int k, double& u, double& v,
                  double& h) const;
  static double leanHeight(const LeanPlane& p, double u, double v);
  // This index's state among every index's in the process, renewed by each edit: a cursor's
  // memo holds only for the state it was made in (an index built later in the same memory, or
  // this one edited, is another).
  std::uint64_t generation_ = nextSerial();
  // The quadtree. On a regular grid the fast path answers every height query without it, so it
  // is built on first need (statistics, all(), edits, shadows, tree files), once, thread-safely.
  mutable Quadtree tree_;
  void ensureTree() const {
    if (deferredTree_) std::call_once(deferred_->once, [this] { buildDeferredTree(); });
  }
  void buildDeferredTree() const;
  bool deferredTree_ = false;
  struct Deferred {  // behind a pointer: once_flag, atomic and mutex do not move
    std::once_flag once;
    std::atomic<bool> built{false};
    std::mutex stats;  // the lazily refreshed stats_
    // segmentMeets' node heights (nodeTops_), made on first need for this edit generation + 1.
    std::mutex tops;
    std::atomic<std::uint64_t> topsFor{0};
  };
  mutable std::vector<float> nodeTops_;  // per quadtree node, the greatest hhi of its triangles
  void ensureNodeTops() const;
  std::uint64_t recordBytesBeforeTree_ = 0;  // tris_ before a deferred build (it may add them)
  std::unique_ptr<Deferred> deferred_ = std::make_unique<Deferred>();
  QuadtreeOptions deferredOptions_;
  unsigned buildThreads_ = 0;               // IndexOptions::buildThreads, for the deferred tree too
  mutable double floorU_ = 0, floorV_ = 0;  // the tree's node size floor (setTreeFloor)
  void setTreeFloor(const std::vector<Box2>& boxes) const;
  // The quadtree over the triangles' boxes (removed polygons left out) and its single-layer
  // leaves: the build, the deferred build and the edits' rebuild.
  void buildTreeOver(const std::vector<Box2>& boxes, const Box2& domain, const QuadtreeOptions& options, double minU,
                     double minV, unsigned threads) const;
  std::uint64_t baseMemoryBytes_ = 0;  // everything but the tree and the triangle records
  mutable IndexStats stats_;
  mutable bool treeStatsStale_ = false;
};

// The QOTA index of a planar mapping M: the core above over M's frame, and the mapping.
template <PlanarMapping M>
class PlanarIndex : public PlanarCore {
 public:
  using Mapping = M;
  PlanarIndex(const Mesh& mesh, const M& mapping, const IndexOptions& options = {})
      : PlanarCore(mesh, mapping.frame(), options), mapping_(mapping) {}
  PlanarIndex(const GridMesh& grid, const M& mapping, const IndexOptions& options = {})
      : PlanarCore(grid, mapping.frame(), options), mapping_(mapping) {}
  const M& mapping() const { return mapping_; }

 private:
  friend struct TreeFileAccess;
  explicit PlanarIndex(const M& mapping) : mapping_(mapping) {}  // a tree file's, filled by it
  M mapping_;
};

// The index of the Cartesian mapping (any gravity): the paper's. Named as its siblings are;
// TerrainIndex, its name until 0.2, is kept as a deprecated alias.
using CartesianIndex = PlanarIndex<CartesianMapping>;
using TerrainIndex [[deprecated("TerrainIndex is now CartesianIndex")]] = CartesianIndex;
using EnuIndex = PlanarIndex<EnuMapping>;  // ECEF data in a local east-north-up frame

// occludedAbove's exact test of one triangle, from its mapped corners (u, v, h) in the polygon's
// own order: whether its projection covers (u, v) (closed, by exact predicates) and its plane lies
// strictly above h there. The index makes its records from the same corners with the same
// arithmetic, so this is the answer the quadtree would give for that triangle: a caller that finds
// its candidates another way (the shadow mask's strips) decides them as the quadtree does, without
// building one. A triangle seen edge-on (zero projected area) covers nothing, as in the index.
bool mappedTriangleAbove(const Eigen::Vector3d& c0, const Eigen::Vector3d& c1, const Eigen::Vector3d& c2, double u,
                         double v, double h);

}  // namespace qota
