// The brute-force oracle the tests hold qota to: the line through a world point along gravity,
// intersected with every triangle of every polygon of the mesh, in the world frame, without any
// of qota's code. Each crossing reports how far inside its polygon it is (the smallest
// barycentric coordinate, scaled to a length), so a test can tell unambiguous answers (well
// inside or well outside every polygon) from points within rounding of an edge.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <cstdint>
#include <vector>

#include "qota/mesh.hpp"

namespace qota::test {

struct OracleHit {
  double height;  // along -gravity, measured from `origin` (the mapped h)
  std::uint32_t polygon;
  double margin;  // > 0 inside, < 0 outside: signed distance-like value from the nearest edge
};

struct OracleResult {
  std::vector<OracleHit> hits;  // every polygon the line crosses (margin >= 0), any order
  double nearestEdge = 1e300;   // smallest |margin| over all polygons the line passes near
};

// gravity: unit vector. origin: the mapping's origin (heights are -gravity . (X - origin)).
inline OracleResult bruteForce(const Mesh& mesh, const Eigen::Vector3d& gravity, const Eigen::Vector3d& origin,
                               const Eigen::Vector3d& p) {
  OracleResult r;
  // A frame with gravity as its third axis, to measure in-plane distances.
  const Eigen::Vector3d e1 = gravity.unitOrthogonal(), e2 = gravity.cross(e1);
  for (std::size_t poly = 0; poly < mesh.polygonCount(); ++poly) {
    const auto idx = mesh.polygon(poly);
    bool hitThis = false;
    double bestMargin = -1e300, bestHeight = 0;
    for (std::size_t k = 1; k + 1 < idx.size(); ++k) {
      const Eigen::Vector3d a = mesh.vertices[idx[0]], b = mesh.vertices[idx[k]], c = mesh.vertices[idx[k + 1]];
      // Project corners and p onto the plane perpendicular to gravity (relative to p).
      auto proj = [&](const Eigen::Vector3d& x) {
        const Eigen::Vector3d d = x - p;
        return Eigen::Vector2d(d.dot(e1), d.dot(e2));
      };
      const Eigen::Vector2d A = proj(a), B = proj(b), C = proj(c);
      const double area = (B - A).x() * (C - A).y() - (B - A).y() * (C - A).x();
      if (area == 0) continue;
      // Barycentric coordinates of the origin (p) in the projected triangle.
      const double wa = (B.x() * C.y() - B.y() * C.x()) / area;
      const double wb = (C.x() * A.y() - C.y() * A.x()) / area;
      const double wc = 1.0 - wa - wb;
      const double scale = std::sqrt(std::fabs(area));
      const double margin = std::min({wa, wb, wc}) * scale;
      if (margin > bestMargin) {
        bestMargin = margin;
        const Eigen::Vector3d X = wa * a + wb * b + wc * c;
        bestHeight = -gravity.dot(X - origin);
      }
      if (margin >= 0) hitThis = true;
    }
    if (bestMargin > -1e300) r.nearestEdge = std::min(r.nearestEdge, std::fabs(bestMargin));
    if (hitThis) r.hits.push_back({bestHeight, static_cast<std::uint32_t>(poly), bestMargin});
  }
  return r;
}

}  // namespace qota::test
