// Polygon triangulation for the mesh readers (private to lib/sources: not a public qota/ header).
//
// A face is looked at in the coordinate plane it is most nearly parallel to; dropping a coordinate
// is exact, so every turn is decided by orient2dSign on the file's own numbers. A face that is
// convex in that plane and has no holes is kept whole; any other is cut into triangles by ear
// clipping, its holes first joined to its outline by bridges.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <vector>

namespace qota::detail {

// Exact: are the three points on one line in 3D? (All three coordinate-plane shadows collinear.)
bool collinear3(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c);

// How a face was cut.
struct FaceCut {
  enum Status {
    whole,           // keep the outline as one polygon: a triangle, or convex (keepConvex)
    triangles,       // cut into `pieces`
    holesNotJoined,  // a hole could not be bridged to the outline (outside it, or rings cross)
    notSimple,       // ear clipping failed, or its triangles do not cover the face's area
  };
  Status status = whole;
  // With `triangles`: corners as mesh vertex indices, counter-clockwise in the projection plane.
  std::vector<std::array<std::uint32_t, 3>> pieces;
};

// Cuts the face with the given outline and holes (mesh vertex indices into `vertices`, repeated
// consecutive corners removed, none of them degenerate) into triangles, or keeps it whole when it
// is a triangle, or, with keepConvex, when it has no holes and is convex in its plane. Quadratic
// in the corners (cubic at worst).
FaceCut cutFace(const std::vector<std::uint32_t>& outline, const std::vector<std::vector<std::uint32_t>>& holes,
                const std::vector<Eigen::Vector3d>& vertices, bool keepConvex);

}  // namespace qota::detail
