// Shadows of a directional light on a DEM, through a QOTA "shadow quadtree" (MERL TR-96-17,
// "Future Directions"): the same index as for terrain following, with the light's direction of
// travel as the preferred direction. A point is in shadow when the line from it toward the light
// meets terrain strictly above it, i.e. between it and the light.
//
// Rule: each pixel centre is a vertex of the terrain (see dem.hpp). It is in shadow when
// - another triangle lies strictly between it and the light (cast shadow): its own triangles
//   (those with it as a corner) are excluded by construction, since they meet its line only at
//   the point itself; any other triangle containing the line's position in the light's frame at
//   a height strictly above the point's shades it. No tolerance is added, so a ridge one triangle
//   thin still casts its shadow; the inside test is exact (see terrain.hpp);
// - or the light arrives from below its own surface (attached shadow): seen from above, the
//   light's horizontal direction leaves the vertex across one of its own triangles, and the light
//   rises more slowly than that triangle in that direction. (Inside the terrain such a ray always
//   meets another triangle on its way out; this catches the rays that leave through a void or the
//   raster's border instead.)
// The sun is treated as a point (no penumbra). The shadow index holds only the triangles that
// face away from the light: a ray that starts into the open air meets terrain first by entering
// it, through such a triangle, so the others cannot change the answer (shadow.cpp). The test of
// a candidate triangle is always the shadow index's exact one; how the candidates are found is
// ShadowSearch (below): through the index's own quadtree, or by default through strips along the
// sun's azimuth that need no tree.
//
// Frame: the DEM in metres, east-north-up at its centre, on its body's ellipsoid (shadow_frame.hpp).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "qota/shadow_frame.hpp"
#include "qota/terrain.hpp"

namespace qota {

// Progress: fraction done in [0, 1] and a message; return false to cancel (then qota::Error).
using Progress = std::function<bool(double, const char*)>;

enum class Light : std::uint8_t { Shadow = 0, Lit = 1, NoData = 2 };

// The light at every pixel centre of the frame's grid (pixelCount() entries, row-major).
// towardLight: vector toward the light in the frame. In a flat frame a light at or below the
// horizon (z <= 0) leaves every pixel in shadow; on an ellipsoid each pixel has its own horizon.
// threads: how many to test pixels with; 0 = one per core.
// How shadowMask finds the triangles a pixel's light ray may meet. Both give the same mask
// (tested on every pixel); each candidate passes the shadow quadtree's exact test.
enum class ShadowSearch {
  // Strips one pixel wide along the sun's azimuth, each holding the occluding triangles it
  // meets sorted by distance along the azimuth; a ray searches its strip from its own pixel on,
  // skipping blocks of triangles that cannot reach its height (shadow.cpp), and decides the rest
  // with mappedTriangleAbove (terrain.hpp), the index's test from the corners. No index and no
  // light-frame tree, whose build at a low sun (most of the terrain facing away from the light,
  // in long slivers) costs more than all the queries. Needs a sun not straight overhead (else
  // Quadtree).
  Strips,
  // The paper's shadow quadtree, built in the light's frame.
  Quadtree,
};
// testOnly: the pixels to test, in the frame's own columns and rows (the others are left NoData);
// all of them when not given. The others still occlude.
std::vector<Light> shadowMask(const LocalFrame& frame, const Eigen::Vector3d& towardLight,
                              const IndexOptions& options = {}, const Progress& progress = {}, unsigned threads = 0,
                              ShadowSearch search = ShadowSearch::Strips,
                              std::optional<PixelWindow> testOnly = std::nullopt);

// How far (metres) a shadow can reach across the raster's edge: relief / tan(altitude).
double shadowReach(const LocalFrame& frame, const Eigen::Vector3d& towardLight);

}  // namespace qota
