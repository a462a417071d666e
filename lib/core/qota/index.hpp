// The one face of every index (CartesianIndex for the planar mappings, CurvedIndex<M> for the
// curved ones): the same calls, names and policies whatever the mapping.
//
// Policy: "no terrain" is std::nullopt (an empty vector for all(), alongLine()); a query that is
// outside the mapping's domain (NaN, a latitude beyond the poles) has no terrain either, and
// never throws, so a batch always finishes. A batch's output must have room for every point
// (else qota::Error, before any work). Heights are the mapping's h; "below" means further along
// the mapping's down (a smaller radius, a larger distance from a station's axis). Ties go to the
// smallest polygon id. A built index is immutable and may be queried from any number of threads;
// edits (insertPolygon, removePolygon) are not thread-safe against queries.
#pragma once

#include <Eigen/Core>
#include <concepts>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "qota/index_face.hpp"
#include "qota/quadtree.hpp"
#include "qota/vocabulary.hpp"

namespace qota {

/// How far an answer may be from the exact one, relative to the terrain's size: a returned
/// height, world point or line parameter is within kAnswerAccuracy * S of the exact intersection
/// of the query's line with the polygon's plane (S: the largest distance of a vertex from the
/// world origin), and the polygon returned is the exact one unless the line passes within that
/// distance of its outline (then a neighbour sharing the edge may be answered). Measured in
/// double precision against an exact oracle on every mapping by tests/test_index_typed.cpp;
/// the grid path and the quadtree answer the same bits.
inline constexpr double kAnswerAccuracy = 1e-10;

// Cursor (index_face.hpp): a query's memory of the last leaf (and, on a grid, the last
// triangle): a query a small step from the last one skips the descent. One per moving object
// and thread.

template <class I>
concept TerrainQuery = requires(const I& index, double u, double v, double h, const Eigen::Vector3d& p, Cursor& cursor,
                                std::span<const Point2> points, std::span<const double> zs,
                                std::span<std::optional<double>> out, unsigned threads) {
  index.mapping();
  // At a point (u, v) of the mapped plane.
  { index.below(u, v, h) } -> std::same_as<std::optional<Hit>>;  // nearest with height <= h
  { index.above(u, v, h) } -> std::same_as<std::optional<Hit>>;  // nearest with height >= h
  { index.bracket(u, v, h) } -> std::same_as<Bracket>;
  { index.top(u, v) } -> std::same_as<std::optional<Hit>>;        // the highest
  { index.all(u, v) } -> std::same_as<std::vector<Hit>>;          // every hit, top first
  { index.height(u, v) } -> std::same_as<std::optional<double>>;  // top's height
  { index.heightBelow(u, v, h) } -> std::same_as<std::optional<double>>;
  // At a world point: the mapping's line through it.
  { index.belowWorld(p) } -> std::same_as<std::optional<Hit>>;
  { index.aboveWorld(p) } -> std::same_as<std::optional<Hit>>;
  { index.bracketWorld(p) } -> std::same_as<Bracket>;
  { index.topWorld(p) } -> std::same_as<std::optional<Hit>>;
  { index.allWorld(p) } -> std::same_as<std::vector<Hit>>;
  // Coherent walks: the same answers, from a cursor.
  { index.below(cursor, u, v, h) } -> std::same_as<std::optional<Hit>>;
  { index.above(cursor, u, v, h) } -> std::same_as<std::optional<Hit>>;
  { index.height(cursor, u, v) } -> std::same_as<std::optional<double>>;
  { index.heightBelow(cursor, u, v, h) } -> std::same_as<std::optional<double>>;
  // Batches (out[i] for points[i]; one z for all, or zs[i] for each), on one thread or several.
  index.heights(points, out);
  index.heightsBelow(points, h, out);
  index.heightsBelow(points, zs, out);
  index.heightsParallel(points, out, threads);
  index.heightsBelowParallel(points, h, out, threads);
  index.heightsBelowParallel(points, zs, out, threads);
  // Any world line origin + t direction, t in [tmin, tmax]: every crossing, nearest t first.
  { index.alongLine(p, p, h, h) } -> std::same_as<std::vector<LineHit>>;
  // What it holds.
  { index.stats() } -> std::convertible_to<const IndexStats&>;
  { index.memoryBytesNow() } -> std::same_as<std::uint64_t>;
  { index.tree() } -> std::convertible_to<const Quadtree&>;
  { index.testsAt(u, v) } -> std::same_as<std::uint32_t>;
};

// The edits every index takes (the paper's dynamic insertion).
template <class I>
concept EditableTerrain = TerrainQuery<I> &&
    requires(I& index, std::span<const Eigen::Vector3d> corners, std::uint32_t polygon) {
  { index.insertPolygon(corners) } -> std::same_as<std::uint32_t>;
  { index.removePolygon(polygon) } -> std::same_as<bool>;
};

}  // namespace qota
