// CurvedIndex: the QOTA query structure for the curved mappings (spherical, cylindrical,
// geodetic), on the same quadtree core as the Cartesian CartesianIndex.
//
// In a curved mapping the line of (u, v) is not vertical, and a 3D triangle's projection into
// (u, v) has curved edges. So the quadtree is used only to find candidates: each triangle is
// referenced from every leaf its footprint box meets, where the footprint box is a conservative
// (u, v) box of every line that can meet the triangle. The hit itself is exact for the 3D
// triangle: the mapping's line meets it when the line lies on the inner side of the three planes
// through the line's origin and each edge.
//
// Local frame: every mapping here has a symmetry axis. Vertices are stored in a local frame with
// that axis as +z and the centre (or axis point) at 0: the world itself for the geodetic mapping,
// world - centre for the sphere, the cylinder's rotation for the cylinder. The line of (u, v) is
// then O + t d with O = (0, 0, s) on the axis: s = 0 for the sphere (the centre), s = v for the
// cylinder (d is horizontal), s = -N e^2 sin(phi) for the ellipsoid normal.
//
// Edge test (watertight): for edge (a, b) the sign of det[a - O; b - O; d]. It is evaluated in
// floating point as d . (a x b) - s (d_x (a_y - b_y) - d_y (a_x - b_x)), whose value for the edge
// (b, a) of a neighbouring triangle is the exact negation, bit for bit; when it is within its
// error bound of zero, the exact predicate (orient3dSign) decides. So adjacent triangles always
// agree on which side of their shared edge a line passes, and a line exactly through a shared
// vertex or edge meets at least one of them: a closed surface has no cracks. A triangle is hit
// when its three signs agree (zeros allowed, winding ignored) and the hit is on the line's
// positive side (t > 0: not behind the centre or the axis).
//
// Footprint boxes: u ranges come from the vertex angles around the axis (each edge covers the
// shorter arc; a triangle around the axis covers all of u), v ranges from the vertices plus each
// edge's interior extremum (great-circle arcs for the sphere; for the ellipsoid the same on the
// axis-scaled vertices, widened by the triangle's height range, see curved.cpp). Boxes are
// padded for the rounding of a query's direction. Polar caps: near a pole (|v| > 90 - 1e-6
// degrees) longitude is ill-conditioned, so queries there test the short list of triangles that
// reach that close to the pole instead of the tree.
//
// Polygons of more than 3 vertices are fanned from their first vertex. Degenerate triangles
// (zero area) are left out and counted. Ties between equally near hits go to the smallest polygon
// id, as in CartesianIndex.
//
// Thread safety: a built index is immutable; any number of threads may query it at once.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <unordered_map>
#include <vector>

#include "qota/axial.hpp"
#include "qota/cylindrical.hpp"
#include "qota/geodetic.hpp"
#include "qota/index_face.hpp"
#include "qota/memory.hpp"
#include "qota/mesh.hpp"
#include "qota/polygon_ledger.hpp"
#include "qota/quadtree.hpp"
#include "qota/spherical.hpp"
#include "qota/terrain.hpp"

namespace qota {

// M is an axial mapping: SphericalMapping, CylindricalMapping or GeodeticMapping (explicitly
// instantiated in curved.cpp). Hits carry heights in the mapping's h, world points and world normals (pointing
// up, against down).
template <AxialMapping M>
class CurvedIndex : public IndexFace<CurvedIndex<M>> {
 public:
  // Throws qota::Error for polygons with fewer than 3 vertices, out-of-range indices or
  // non-finite vertices, naming the polygon.
  CurvedIndex(const Mesh& mesh, const M& mapping, const IndexOptions& options = {});

  // The face (index_face.hpp): below, above, bracket, top, height, heightBelow at (u, v) in
  // degrees (u any value, wrapped; v in [-90, 90] for the sphere and the ellipsoid: outside it,
  // or not finite, there is no terrain), from a cursor, at a world point (mapped first) and in
  // batches, "below" meaning further along down: a smaller radius or ellipsoid height, a larger
  // distance from a cylinder's axis; and here every hit at (u, v), top to bottom.
  std::vector<Hit> all(double u, double v) const;

  // Every crossing of any world line origin + t direction, t in [tmin, tmax], nearest t first
  // (equal t: smaller polygon id), with the exact edge test on the corners' offsets from the
  // line's origin (neighbours agree on a shared edge). A scan of every triangle: for occasional
  // lines (a scene's tilted part), not for a stream of queries.
  std::vector<LineHit> alongLine(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                                 double tmin = -std::numeric_limits<double>::infinity(),
                                 double tmax = std::numeric_limits<double>::infinity()) const;

  // Dynamic edits, as CartesianIndex's: insertPolygon adds a polygon by its world corners (ids
  // continue after the mesh's), into every leaf its footprint meets (leaves split by the build's
  // rule; a footprint outside the tree's box grows it and rebuilds the tree); removePolygon takes
  // one out (false when there is no such live polygon). The answers then equal an index built
  // from scratch on the live polygons. Not thread-safe against concurrent queries.
  std::uint32_t insertPolygon(std::span<const Eigen::Vector3d> corners);
  bool removePolygon(std::uint32_t polygon);

  const M& mapping() const { return mapping_; }
  // Thread-safe with queries and with itself (not with edits, which nothing is).
  const IndexStats& stats() const {
    const std::lock_guard<std::mutex> lock(*statsMutex_);
    if (treeStatsStale_) stats_.tree = tree_.stats(), treeStatsStale_ = false;  // after edits
    return stats_;
  }
  std::uint64_t memoryBytesNow() const { return stats().memoryBytes; }
  const Quadtree& tree() const { return tree_; }
  // Candidate triangles a query at (u, v) looks at.
  std::uint32_t testsAt(double u, double v) const;

  // The query line in the local frame, exposed for tests: O = (0, 0, s), direction d (unit,
  // pointing to increasing t), and the height of the point O + t d is heightAt(t).
  struct Line {
    double s;
    double d[3];
    double hOffset;  // the height of O + t d is t - hOffset (geodetic: N at the latitude; else 0)
    double bound;    // error bound of the filtered edge tests on this line
  };
  Line lineAt(double u, double v) const;

 private:
  friend struct TreeFileAccess;  // the on-disk format (treefile.hpp)
  friend class IndexFace<CurvedIndex>;
  CurvedIndex() = default;
  // The face's primitives (index_face.hpp).
  std::optional<Hit> hitBelow(double u, double v, double h, Cursor* cursor) const;
  std::optional<Hit> hitAbove(double u, double v, double h, Cursor* cursor) const;
  std::optional<double> heightQuery(double u, double v, double z, Cursor* cursor) const {
    return heightAt(u, v, z, cursor);
  }
  bool toQuery(const Eigen::Vector3d& world, Eigen::Vector3d& m) const { return mapped(world, m); }
  void batchBelow(std::span<const Point2> points, double z, std::span<std::optional<double>> out) const;
  void batchBelow(std::span<const Point2> points, std::span<const double> zs,
                  std::span<std::optional<double>> out) const;
  void beforeParallel() const {}
  // One triangle, 128 bytes: its local vertices (for the edge tests and the exact fallback), the
  // plane n . x = na, the footprint box (float, rounded outward) and the source polygon.
  struct alignas(64) Tri {
    double p[3][3];
    double n[3];
    double na;
    float ulo, uhi, vlo, vhi;  // uhi may exceed 180 (a box across the seam)
    std::uint32_t polygon;
    std::uint32_t reserved = 0;  // tree files store records as they are: no byte left to chance
  };
  static_assert(sizeof(Tri) == 128);
  // A footprint box in (u, v); ulo in [-180, 180), uhi <= ulo + 360 (past 180 across the seam).
  struct FootBox {
    double ulo, uhi, vlo, vhi;
  };
  bool makeTriangle(const Eigen::Vector3d (&p)[3], const double (&vertexHeight)[3], std::uint32_t poly, Tri& t,
                    FootBox& box) const;
  void addToPolarLists(std::uint32_t i, const FootBox& box);
  // The tree's overlap test: the record's float box (rounded outward) against a node's box, with
  // the seam; the same at build and on edits.
  bool overlaps(std::uint32_t i, const Box2& b) const {
    const Tri& f = tris_[i];
    if (f.vlo > b.vhi || f.vhi < b.vlo) return false;
    return (f.ulo <= b.uhi && f.uhi >= b.ulo) || (f.ulo - 360.0 <= b.uhi && f.uhi - 360.0 >= b.ulo);
  }
  bool live(std::uint32_t i) const { return !ledger_.removed(tris_[i].polygon); }
  void rebuildTree(Box2 root);

  double normalizeU(double u) const;
  bool validQuery(double u, double v) const;  // finite, and within the latitudes where there are any
  bool mapped(const Eigen::Vector3d& world, Eigen::Vector3d& m) const;  // false: no (u, v, h) there
  bool polar(double v) const;
  // Whether the line meets triangle t; t_out is the line parameter of the hit.
  bool hits(const Tri& t, const Line& line, double& tOut) const;
  int edgeSign(const double* a, const double* b, const Line& line, double bound) const;
  double heightOf(const Line& line, double t) const { return t - line.hOffset; }
  double elevation(double h) const { return M::kHeightUp ? h : -h; }
  // Calls visit(i) for every candidate triangle of (u, v); sets line (to storage) before the
  // first call (the line is computed while the candidates load).
  template <class Visit>
  void forCandidates(double u, double v, const Line*& line, Line& storage, Visit&& visit) const;
  static bool inBox(const Tri& t, double u, double v) {
    return v >= t.vlo && v <= t.vhi && ((u >= t.ulo && u <= t.uhi) || u + 360.0 <= t.uhi);
  }
  void prefetch(std::span<const std::uint32_t> items) const;
  template <bool Below>
  std::uint32_t nearestIn(std::span<const std::uint32_t> items, bool checkBox, double u, double v, const Line& line,
                          double ez, double& hOut, double& tOut) const;
  template <bool Below>
  std::uint32_t nearest(double u, double v, double h, double& hOut, Line& line, double& tOut,
                        Cursor* cursor = nullptr) const;
  Hit makeHit(std::uint32_t t, const Line& line, double tHit) const;
  // below/above/height with or without a cursor.
  template <bool Below>
  std::optional<Hit> hitAt(double u, double v, double h, Cursor* cursor) const;
  std::optional<double> heightAt(double u, double v, double z, Cursor* cursor) const;
  template <class ZOf>  // z of point i: zOf(i)
  void heightsBelowBatch(std::span<const Point2> points, const ZOf& zOf, std::span<std::optional<double>> out) const;
  // The top of the mapping's h ("below" any terrain) in the direction of up.
  static constexpr double kTop =
      M::kHeightUp ? std::numeric_limits<double>::infinity() : -std::numeric_limits<double>::infinity();

  M mapping_;
  BigVector<Tri> tris_;
  std::vector<std::uint32_t> polarNorth_, polarSouth_;
  Quadtree tree_;
  double scale_ = 0;      // max L1 norm of a local vertex: sets the edge tests' error bound
  PolygonLedger ledger_;  // edits: the removed polygons, each polygon's triangles
  mutable IndexStats stats_;
  mutable bool treeStatsStale_ = false;
  std::unique_ptr<std::mutex> statsMutex_ = std::make_unique<std::mutex>();  // (a mutex does not move)
};

using SphericalIndex = CurvedIndex<SphericalMapping>;
using CylindricalIndex = CurvedIndex<CylindricalMapping>;
using GeodeticIndex = CurvedIndex<GeodeticMapping>;

}  // namespace qota
