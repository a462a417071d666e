// The face every index shows (index.hpp's TerrainQuery), written once: the plain, cursor,
// world-point and batch forms of a query, from the few primitives each index implements. An
// index I derives from IndexFace<I> (and befriends it) and provides, privately:
//
//   std::optional<Hit> hitBelow(u, v, h, Cursor*) const;   nearest hit with height <= h
//   std::optional<Hit> hitAbove(u, v, h, Cursor*) const;   nearest hit with height >= h
//   std::optional<double> heightQuery(u, v, z, Cursor*) const;  hitBelow's height alone
//   bool toQuery(const Eigen::Vector3d& world, Eigen::Vector3d& m) const;
//       the world point's mapped (u, v, h); false where the mapping has none
//   void batchBelow(points, z, out) const; void batchBelow(points, zs, out) const;
//       heights below one z (or zs[i]) for a slice of points, out sized for them
//   void beforeParallel() const;  what must be made once before the slices run on threads
//   static constexpr double kTop;  an h above any terrain ("below" it finds the top)
//
// and, publicly, all(u, v) (every hit, top first). (u, v) are the mapping's; "below" means
// further along the mapping's down. Cursor forms remember the last leaf (and triangle) so that
// a query a small step from the last skips the descent, with identical answers; a cursor
// belongs to one moving object and one thread.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "qota/batch.hpp"
#include "qota/quadtree.hpp"
#include "qota/vocabulary.hpp"

namespace qota {

/// A moving object's memory for coherent queries, one per object and thread: the quadtree's last
/// leaf and the leaves ahead of its walk (Quadtree::Cursor, valid for the tree and edit of its
/// stamp), and the index's memo of its last answer (the grid path keeps the last triangle's
/// plane there, so that a walk within one triangle solves no plane), valid only for that index
/// (owner) in that state (generation: unique in the process, renewed by edits), at that key.
struct Cursor : Quadtree::Cursor {
  struct Memo {
    const void* owner = nullptr;
    std::uint64_t generation = 0, key = 0;
    std::uint32_t item = 0;
    double value[7] = {};
  } memo;
};

template <class I>
class IndexFace {
 public:
  /// Nearest terrain at (u, v) with height <= h (below) or >= h (above); nullopt for none.
  std::optional<Hit> below(double u, double v, double h) const { return self().hitBelow(u, v, h, nullptr); }
  std::optional<Hit> above(double u, double v, double h) const { return self().hitAbove(u, v, h, nullptr); }
  /// Both: the floor below and the ceiling above (the paper's containment).
  Bracket bracket(double u, double v, double h) const { return {below(u, v, h), above(u, v, h)}; }
  /// The highest terrain at (u, v) (up: against the mapping's down).
  std::optional<Hit> top(double u, double v) const { return below(u, v, I::kTop); }
  /// Height only, the fast path: top's height, or the nearest height <= z.
  std::optional<double> height(double u, double v) const { return self().heightQuery(u, v, I::kTop, nullptr); }
  std::optional<double> heightBelow(double u, double v, double z) const { return self().heightQuery(u, v, z, nullptr); }

  /// The same from a cursor (temporal coherence).
  std::optional<Hit> below(Cursor& cursor, double u, double v, double h) const {
    return self().hitBelow(u, v, h, &cursor);
  }
  std::optional<Hit> above(Cursor& cursor, double u, double v, double h) const {
    return self().hitAbove(u, v, h, &cursor);
  }
  std::optional<double> height(Cursor& cursor, double u, double v) const {
    return self().heightQuery(u, v, I::kTop, &cursor);
  }
  std::optional<double> heightBelow(Cursor& cursor, double u, double v, double z) const {
    return self().heightQuery(u, v, z, &cursor);
  }

  /// At a world point: the mapping's line through it, its h the point's. No terrain where the
  /// mapping has no (u, v) (a point on a sphere's centre or a station's axis).
  std::optional<Hit> belowWorld(const Eigen::Vector3d& p) const {
    Eigen::Vector3d m;
    return self().toQuery(p, m) ? below(m.x(), m.y(), m.z()) : std::nullopt;
  }
  std::optional<Hit> aboveWorld(const Eigen::Vector3d& p) const {
    Eigen::Vector3d m;
    return self().toQuery(p, m) ? above(m.x(), m.y(), m.z()) : std::nullopt;
  }
  Bracket bracketWorld(const Eigen::Vector3d& p) const {
    Eigen::Vector3d m;
    return self().toQuery(p, m) ? bracket(m.x(), m.y(), m.z()) : Bracket{};
  }
  std::optional<Hit> topWorld(const Eigen::Vector3d& p) const {
    Eigen::Vector3d m;
    return self().toQuery(p, m) ? top(m.x(), m.y()) : std::nullopt;
  }
  std::vector<Hit> allWorld(const Eigen::Vector3d& p) const {
    Eigen::Vector3d m;
    return self().toQuery(p, m) ? self().all(m.x(), m.y()) : std::vector<Hit>{};
  }

  /// Heights for many points at once (out[i] for points[i]), the top or below one z or zs[i]:
  /// the same answers as one at a time, with the memory latency of the points overlapped
  /// (several times faster on terrains larger than the cache). out (and zs) must have room for
  /// every point, else qota::Error before any work.
  void heights(std::span<const Point2> points, std::span<std::optional<double>> out) const {
    heightsBelow(points, I::kTop, out);
  }
  void heightsBelow(std::span<const Point2> points, double z, std::span<std::optional<double>> out) const {
    batch::requireRoom("heightsBelow", points.size(), out.size());
    self().batchBelow(points, z, out);
  }
  void heightsBelow(std::span<const Point2> points, std::span<const double> zs,
                    std::span<std::optional<double>> out) const {
    batch::requireRoom("heightsBelow", points.size(), std::min(out.size(), zs.size()));
    self().batchBelow(points, zs, out);
  }

  /// The same on several threads (0: one per hardware thread), each taking an equal slice of
  /// the points; worth it from some ten thousand points. The answers do not depend on the
  /// threads.
  void heightsParallel(std::span<const Point2> points, std::span<std::optional<double>> out,
                       unsigned threads = 0) const {
    heightsBelowParallel(points, I::kTop, out, threads);
  }
  void heightsBelowParallel(std::span<const Point2> points, double z, std::span<std::optional<double>> out,
                            unsigned threads = 0) const {
    batch::requireRoom("heightsBelowParallel", points.size(), out.size());
    self().beforeParallel();
    batch::inSlices(points.size(), threads, kPerThread, [&](std::size_t lo, std::size_t hi) {
      self().batchBelow(points.subspan(lo, hi - lo), z, out.subspan(lo, hi - lo));
    });
  }
  void heightsBelowParallel(std::span<const Point2> points, std::span<const double> zs,
                            std::span<std::optional<double>> out, unsigned threads = 0) const {
    batch::requireRoom("heightsBelowParallel", points.size(), std::min(out.size(), zs.size()));
    self().beforeParallel();
    batch::inSlices(points.size(), threads, kPerThread, [&](std::size_t lo, std::size_t hi) {
      self().batchBelow(points.subspan(lo, hi - lo), zs.subspan(lo, hi - lo), out.subspan(lo, hi - lo));
    });
  }

 protected:
  IndexFace() = default;

 private:
  static constexpr std::size_t kPerThread = 4096;  // fewer points a thread: not worth one
  const I& self() const { return static_cast<const I&>(*this); }
};

}  // namespace qota
