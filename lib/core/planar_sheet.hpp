// Whether a planar index's triangles form one sheet: interiors pairwise disjoint, proved for the
// whole mesh at once instead of pair by pair in every leaf (PlanarCore::prepareLeaf), so the
// build marks every leaf a single layer at the cost of a pass over the edges.
//
// Why the proof holds. Every triangle is counter-clockwise in the plane, so a point inside it
// has winding number 1 about its boundary and a point outside 0: the number of triangles over a
// point off every edge is the winding number about the sum of their boundaries. Where two
// triangles share an edge in opposite directions (a -> b in one, b -> a in the other: they lie on
// either side of it), the two copies cancel in that sum. If every edge is so shared or used once,
// what is left is the mesh's boundary B, and the count over a point is B's winding number there.
// If B is simple closed polygons that meet only at shared vertices, without crossing there, each
// one's winding number is 1 inside it (counter-clockwise) or -1 (clockwise, a hole) and 0
// outside, and the count is their sum: at most 1 everywhere when the loops round each
// counter-clockwise one wind 0 in all (an island inside a hole inside an outer loop; parts side
// by side). Then no point is under two triangles, and no two interiors meet. Where the boundary
// pinches (voids meeting at a corner), the edges round the vertex must alternate, leaving and
// entering, and are paired so that the loops touch there.
//
// Anything else is left to the pairs (false): an edge used twice the same way or three times,
// boundary edges that touch or cross other than at a shared vertex (a ramp that winds over
// itself, two vertices at one place), edges round a pinch that do not alternate (a triangle's
// corner inside another's), a loop inside a counter-clockwise loop with no hole between (a part
// over another), a pinch of more than four edges that a loop comes back to. The tests are on
// vertex numbers and exact orientations only.
#pragma once

#include <cstdint>
#include <span>

#include "qota/grid_path.hpp"  // TriangleCorners
#include "qota/vocabulary.hpp"

namespace qota::detail {

// triangles: counter-clockwise in the plane of `vertices`, none of zero area (trusted: the
// proof rests on it; PlanarCore fans and orients its triangles so); left[t] (when not empty, one
// a triangle): triangle t is not part of the mesh (a removed polygon's). A corner out of range,
// a `left` of another size, or a coordinate beyond the exact predicates' range (magnitudes 1e-150
// to 1e150, or 0) give false.
bool oneSheet(std::span<const TriangleCorners> triangles, std::span<const Point2> vertices,
              std::span<const std::uint8_t> left = {});

}  // namespace qota::detail
