// Terrain following: the paper's uses of a QOTA index beyond one height, for every mapping.
//
// Each function takes any index (the TerrainQuery concept of index.hpp: CartesianIndex, EnuIndex,
// CurvedIndex<M>), so it works in every mapping alike: "up" is always against the mapping's down at the
// point, and "below" is the mapping's (farther from the axis in a station).
//
// - groundUnder: the terrain under a world point, along the mapping's line.
// - poseFromFootprint: the paper's car: the plane through three footprint samples (or the least
//   squares plane through N), giving position, up and a heading-preserving orientation; samples
//   over a hole are reported, never silently dropped.
// - checkMove: can an object go from A to B while staying on walkable terrain: the endpoint (the
//   paper's method), or the whole way, sampled at a given step, stopping at holes, at steps
//   higher than a climbable height (walls and cliffs), and on impassable polygons (water).
// - inLocale / classifyLocale: the paper's containment: a point is inside a locale when it has a
//   floor below and a ceiling above.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <optional>
#include <span>
#include <type_traits>
#include <vector>

#include "qota/index.hpp"
#include "qota/terrain.hpp"

namespace qota {

// A rigid pose: position and orientation (columns: the object's x, y, z axes in the world).
// (qota/glm_interop.hpp turns it into a renderer's model matrix.)
struct Pose {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Matrix3d orientation = Eigen::Matrix3d::Identity();
};

// The pose of an object resting on a hit: up along the normal, heading as near `forward` (a
// world direction) as the surface allows. When forward is parallel to the normal, any
// perpendicular heading is used.
inline Pose poseOnHit(const Hit& hit, const Eigen::Vector3d& forward) {
  const Eigen::Vector3d z = hit.normal.normalized();
  Eigen::Vector3d x = forward - forward.dot(z) * z;
  if (x.squaredNorm() < 1e-24) x = z.unitOrthogonal();
  x.normalize();
  Pose pose;
  pose.position = hit.world;
  pose.orientation.col(0) = x;
  pose.orientation.col(1) = z.cross(x);
  pose.orientation.col(2) = z;
  return pose;
}

template <TerrainQuery Index>
using MappingOf = std::decay_t<decltype(std::declval<const Index&>().mapping())>;

// Unit "up" (against down) of the mapping's line through a world point.
template <TerrainQuery Index>
Eigen::Vector3d upAt(const Index& index, const Eigen::Vector3d& world) {
  const Eigen::Vector3d m = index.mapping().toMapped(world);
  return -index.mapping().line(m.x(), m.y()).down;
}

// The nearest terrain at or below the point raised by `clearance` along up (infinity: the
// topmost terrain on the point's line), or nullopt over a hole.
template <TerrainQuery Index>
std::optional<Hit> groundUnder(const Index& index, const Eigen::Vector3d& world,
                               double clearance = std::numeric_limits<double>::infinity()) {
  const Eigen::Vector3d m = index.mapping().toMapped(world);
  const double sign = MappingOf<Index>::kHeightUp ? 1.0 : -1.0;
  return index.below(m.x(), m.y(), m.z() + sign * clearance);
}

// The plane through points (3: exact; more: least squares, Eigen's self-adjoint eigensolver on
// the covariance): centroid, unit normal (either sign), RMS distance of the points from it.
// False when the points are (nearly) collinear.
bool fitPlane(std::span<const Eigen::Vector3d> points, Eigen::Vector3d& centroid, Eigen::Vector3d& normal, double& rms);

// The pose of an object on a plane through `position` with upward unit normal `normal`, where
// the world's up is `up`: z along the normal, x in the plane and in the vertical plane of
// `heading` (so seen from above the object faces the heading, as a car does on a slope), y = z x
// x. A heading along up falls back to any direction in the plane.
Pose poseOnPlane(const Eigen::Vector3d& position, const Eigen::Vector3d& normal, const Eigen::Vector3d& up,
                 const Eigen::Vector3d& heading);

struct FootprintPose {
  std::optional<Pose> pose;                      // none with fewer than 3 hits or collinear hits
  std::vector<std::optional<Hit>> hits;          // the ground under each sample, in order
  std::vector<std::size_t> missing;              // samples over a hole (a wheel off the edge)
  double rms = 0;                                // RMS distance of the hits from the plane (0 for 3)
  Eigen::Vector3d up = Eigen::Vector3d::Zero();  // the plane's normal, pointing up
};

// Places an object on the terrain from footprint samples (world points, e.g. the wheels, around
// its current position): each sample's ground (groundUnder with `clearance`), the plane through
// them, the object's origin at the centroid of the hits, its z axis along the plane's upward
// normal and its x axis as close to `heading` as the plane allows. The pose is the one of the
// samples that hit; `missing` names the others.
template <TerrainQuery Index>
FootprintPose poseFromFootprint(const Index& index, std::span<const Eigen::Vector3d> samples,
                                const Eigen::Vector3d& heading,
                                double clearance = std::numeric_limits<double>::infinity()) {
  FootprintPose out;
  std::vector<Eigen::Vector3d> points;
  for (std::size_t i = 0; i < samples.size(); ++i) {
    out.hits.push_back(groundUnder(index, samples[i], clearance));
    if (out.hits.back()) {
      points.push_back(out.hits.back()->world);
    } else {
      out.missing.push_back(i);
    }
  }
  Eigen::Vector3d centroid, normal;
  if (points.size() < 3 || !fitPlane(points, centroid, normal, out.rms)) return out;
  const Eigen::Vector3d up = upAt(index, centroid);
  if (normal.dot(up) < 0) normal = -normal;
  out.up = normal;
  out.pose = poseOnPlane(centroid, normal, up, heading);
  return out;
}

// Why a move stops.
enum class MoveBlock {
  None,        // the move is allowed
  Hole,        // no terrain under a point of the way (a hole, a lake left out, off the terrain)
  Step,        // the ground rises or falls more than maxStep between samples (a wall, a cliff)
  Impassable,  // the ground's polygon is marked impassable (water)
};

struct MoveOptions {
  bool wholePath = false;                                    // false: the endpoint only (the paper's check)
  double step = 1.0;                                         // sample spacing along the way, in world units
  double maxStep = std::numeric_limits<double>::infinity();  // climbable height between samples
  double clearance = 1.0;                                    // how far above the object's feet the ground is looked for
  std::function<bool(std::uint32_t polygon)> impassable;     // null: every polygon passable
};

struct MoveResult {
  MoveBlock block = MoveBlock::None;
  double fraction = 1;        // how far along A -> B the object got (0..1)
  Eigen::Vector3d last;       // the last point on walkable ground (A's ground if none)
  std::optional<Hit> ground;  // the ground at `last`
  bool allowed() const { return block == MoveBlock::None; }
};

// Checks a move of an object standing at `from` (its feet) to `to`, following the terrain: the
// way is the straight world segment, each sample dropped to its ground (groundUnder with the
// clearance above the previous ground). Holes are found where a sample has no ground, so a hole
// narrower than `step` between two samples can be missed: pick a step below the smallest gap
// that matters (half a metre for a person).
template <TerrainQuery Index>
MoveResult checkMove(const Index& index, const Eigen::Vector3d& from, const Eigen::Vector3d& to,
                     const MoveOptions& options = {}) {
  MoveResult r;
  r.last = from;
  const double length = (to - from).norm();
  const int n = options.wholePath && length > 0
                    ? static_cast<int>(std::ceil(length / std::max(options.step, 1e-12 * length)))
                    : 1;
  std::optional<Hit> prev = groundUnder(index, from, options.clearance);
  if (!prev) {
    r.block = MoveBlock::Hole, r.fraction = 0;
    return r;
  }
  r.ground = prev;
  r.last = prev->world;
  const double sign = MappingOf<Index>::kHeightUp ? 1.0 : -1.0;
  for (int i = 1; i <= n; ++i) {
    const double f = static_cast<double>(i) / n;
    // The endpoint alone: its own ground, as the object would be placed there. Along the way:
    // the sample at this fraction, lifted to the previous ground's height plus the clearance, so
    // that an overhang above the object (a bridge over its road) is not taken for its ground.
    const Eigen::Vector3d m = index.mapping().toMapped(from + f * (to - from));
    const std::optional<Hit> g = options.wholePath ? index.below(m.x(), m.y(), prev->height + sign * options.clearance)
                                                   : groundUnder(index, to, options.clearance);
    MoveBlock block = MoveBlock::None;
    if (!g) {
      block = MoveBlock::Hole;
    } else if (std::fabs(g->height - prev->height) > options.maxStep) {
      block = MoveBlock::Step;
    } else if (options.impassable && options.impassable(g->polygon)) {
      block = MoveBlock::Impassable;
    }
    if (block != MoveBlock::None) {
      r.block = block;
      r.fraction = static_cast<double>(i - 1) / n;
      return r;
    }
    prev = g;
    r.ground = g;
    r.last = g->world;
  }
  return r;
}

// The paper's containment: inside a locale when there is floor terrain below the point and
// ceiling terrain above it (two indexes; they may be the same one).
template <TerrainQuery FloorIndex, TerrainQuery CeilingIndex>
bool inLocale(const FloorIndex& floor, const CeilingIndex& ceiling, const Eigen::Vector3d& p) {
  const Eigen::Vector3d mf = floor.mapping().toMapped(p);
  if (!floor.below(mf.x(), mf.y(), mf.z())) return false;
  const Eigen::Vector3d mc = ceiling.mapping().toMapped(p);
  return ceiling.above(mc.x(), mc.y(), mc.z()).has_value();
}

// One index holding both: the nearest terrain below must be a floor polygon and the nearest
// above a ceiling polygon (so a point under a second storey's floor is not inside the first).
template <TerrainQuery Index>
bool inLocale(const Index& index, const Eigen::Vector3d& p, const std::function<bool(std::uint32_t)>& isFloor,
              const std::function<bool(std::uint32_t)>& isCeiling) {
  const Eigen::Vector3d m = index.mapping().toMapped(p);
  const std::optional<Hit> below = index.below(m.x(), m.y(), m.z());
  if (!below || !isFloor(below->polygon)) return false;
  const std::optional<Hit> above = index.above(m.x(), m.y(), m.z());
  return above && isCeiling(above->polygon);
}

// inLocale for many points: inside[i] for points[i] (1 inside, 0 outside).
template <TerrainQuery FloorIndex, TerrainQuery CeilingIndex>
std::vector<std::uint8_t> classifyLocale(const FloorIndex& floor, const CeilingIndex& ceiling,
                                         std::span<const Eigen::Vector3d> points) {
  std::vector<std::uint8_t> inside(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) inside[i] = inLocale(floor, ceiling, points[i]);
  return inside;
}

}  // namespace qota
