// The words every index speaks, in one place: points and boxes of the mapped (u, v) plane, the
// quadtree's options and statistics, an index's options and statistics, and what a query answers
// (hits, brackets, line hits). The indexes (terrain.hpp, curved.hpp) and the concept they all
// satisfy (index.hpp) are written in these words.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <optional>

namespace qota {

/// The one "no triangle" value: a grid slot without a triangle, a search that found none, a
/// padding entry. (Triangle numbers are 32-bit; an index holds fewer than this many.)
inline constexpr std::uint32_t kNoTriangle = 0xffffffffu;

/// A point of the mapped plane.
struct Point2 {
  double u = 0, v = 0;
};

/// A closed axis-aligned box [ulo, uhi] x [vlo, vhi]. Empty when ulo > uhi.
struct Box2 {
  double ulo = 1, vlo = 1, uhi = 0, vhi = 0;
  bool empty() const { return !(ulo <= uhi && vlo <= vhi); }
  bool contains(double u, double v) const { return u >= ulo && u <= uhi && v >= vlo && v <= vhi; }
};

struct QuadtreeOptions {
  /// The paper's Maxpoly: a node referencing more items than this is split, unless it is at
  /// maxDepth. Smaller values mean fewer polygon tests per query and a larger tree (the paper's
  /// Table 4). 8 keeps a query to about 8 tests at about 1.5 references per polygon.
  std::uint32_t maxPoly = 8;
  /// The paper's Maxdepth: nodes at this depth (root = 0) are leaves whatever their count. It
  /// bounds the tree where many polygons meet in one point (a fan around a vertex), which no split
  /// can separate. 4^16 leaves is far more than any terrain's polygons.
  std::uint32_t maxDepth = 16;
  /// Where a node is cut. Midpoint: the middle of its box, the paper's rule; the descent needs no
  /// stored cut, and the top levels go through a jump table. CostModel: along each axis the cut,
  /// among 9 evenly spaced candidates in the middle half of the box, that minimises the expected polygon tests of the
  /// two sides (each side's item count, from the items' bounding boxes, weighted by its share of the box, as the
  /// surface-area heuristic of BVH builders does); cuts are stored per node (16 bytes) and the descent reads them (no
  /// jump table). Only for owners that give the build the items' boxes (CartesianIndex); others always cut at the
  /// midpoint.
  enum class Cuts : std::uint8_t { Midpoint, CostModel };
  Cuts cuts = Cuts::Midpoint;
  /// Tree files store this struct as it is: no byte may be left to chance (padding).
  std::uint8_t reserved[3] = {0, 0, 0};
};

/// The statistics of the paper's Table 4, plus the shape of the tree.
struct QuadtreeStats {  // (no padding: tree files store it as it is)
  std::uint64_t nodes = 0;
  std::uint64_t leaves = 0;
  std::uint64_t emptyLeaves = 0;
  std::uint64_t references = 0;  ///< total leaf references (sum of leaf sizes)
  std::uint32_t depth = 0;       ///< deepest leaf (root = 0)
  std::uint32_t maxLeafItems = 0;
  double meanLeafItems = 0;       ///< over all leaves
  double averageTests = 0;        ///< leaf size averaged over the domain's area (Table 4)
  std::uint64_t memoryBytes = 0;  ///< nodes and references
};

/// How an index is built. Options that do not apply to an index's mapping are refused (an error),
/// not ignored.
struct IndexOptions {
  QuadtreeOptions tree;
  /// The direct-indexing fast path for regular grids (a raster from loadDem, a Heightfield), in a
  /// planar mapping (parallel lines: cartesian, enu); unset: on where it applies, and true is an
  /// error for a curved mapping. When the mesh is found to be a grid, a query finds its cell by
  /// arithmetic. A point clearly inside one of the cell's two triangles (farther than 1e-5 cell
  /// from its sides) is answered from the cell's corners alone: the plane is solved from them with
  /// the same arithmetic as the triangle records, so the same bits. A point on or near an edge (a
  /// pixel centre) is decided by the exact test over the triangles of the 3 x 3 cells around it,
  /// the smallest polygon id holding it answering, as in the quadtree's single-layer leaves. So
  /// the same answers as the quadtree (tested), from about 34 bytes per triangle: no triangle
  /// records are kept, and heights that are exact in float (any Int16 or Float32 raster) are read
  /// from a float copy. The records and the quadtree are made when something needs them (edits,
  /// shadows, statistics, tree files).
  std::optional<bool> gridFastPath = std::nullopt;
  /// Threads for the build's parts that split by triangle or by leaf (the triangles' records,
  /// the leaves' single-layer test): 0, one per hardware thread; 1, the calling thread alone.
  /// The index is the same, bit for bit, for any count.
  unsigned buildThreads = 0;
};
/// The names before every index shared one, kept for one release (0.2); to be removed in 0.3.
using TerrainOptions [[deprecated("use qota::IndexOptions")]] = IndexOptions;

/// Where a line of the mapping meets the terrain.
struct Hit {
  double height = 0;          ///< h in mapped coordinates (up = against down)
  Eigen::Vector3d world;      ///< the point in the world frame
  Eigen::Vector3d normal;     ///< unit surface normal in the world frame, pointing up (against down)
  std::uint32_t polygon = 0;  ///< index of the source polygon in the Mesh
};

/// The nearest terrain below and above a point (the paper's floor and ceiling).
struct Bracket {
  std::optional<Hit> below;
  std::optional<Hit> above;
};

/// A hit of an arbitrary line (alongLine): its parameter and the hit.
struct LineHit {
  double t = 0;
  Hit hit;
};

/// What an index holds. (No padding: tree files store it as it is.)
struct IndexStats {
  std::uint64_t polygons = 0;   ///< polygons in the mesh
  std::uint64_t triangles = 0;  ///< triangles in the query structure (polygons are fanned)
  std::uint64_t leftOut = 0;    ///< left out: polygons with no area seen along the mapping's lines
                                /// (walls) in a planar mapping, zero-area triangles in a curved one
  std::uint64_t vertices = 0;
  std::uint64_t polarNorth = 0, polarSouth = 0;  ///< curved: triangles in the polar lists
  Box2 domain;                                   ///< the tree's (u, v) box
  QuadtreeStats tree;
  std::uint64_t memoryBytes = 0;  ///< everything the index holds
};
/// The names before every index shared one, kept for one release (0.2); to be removed in 0.3.
using TerrainStats [[deprecated("use qota::IndexStats")]] = IndexStats;
using CurvedStats [[deprecated("use qota::IndexStats")]] = IndexStats;

}  // namespace qota
