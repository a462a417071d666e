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
// Frame: the DEM in metres around its centre, east-north-up (LocalFrame). A DEM in a geographic
// CRS is put on its ellipsoid (WGS84 unless the CRS says otherwise) with GeographicLib's
// LocalCartesian, so the Earth's curvature lowers distant terrain as it should; `flat` maps
// longitude and latitude linearly instead. A projected DEM uses its own x, y in metres, with the
// sun's azimuth turned from true north to grid north (meridian convergence at the centre).
// Heights are taken as metres.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "qota/dem.hpp"
#include "qota/sun.hpp"
#include "qota/terrain.hpp"

namespace qota {

// The DEM's vertices in a local metric east-north-up frame (same vertex indices as dem.mesh),
// with every cell's two triangles. Voids are filled from their rims for occlusion: light cannot
// pass under the terrain through missing data, and every vertex has a full ring of triangles.
// Their cells stay nodata (valid = 0) in every output.
struct LocalFrame {
  Mesh mesh;
  std::vector<std::uint8_t> valid;  // the DEM has a height at this cell
  int width = 0, height = 0;
  bool geographicLocation = false;  // centreLon/Lat are known (the DEM has a CRS)
  double centreLon = 0, centreLat = 0;
  // Clockwise angle (degrees) from the frame's +y axis to true north: 0 for east-north-up
  // frames, the meridian convergence for grid frames.
  double trueNorthFromY = 0;
  double minHeight = 0, maxHeight = 0;  // over valid cells
  double pixelSizeX = 1, pixelSizeY = 1;  // metres, at the centre
  std::string description;
  // Set by localFrame: mesh is the grid's two triangles per cell, cells in row order, each split
  // from its top-left corner (tl, bl, br then tl, br, tr). The shadow mask then finds a vertex's
  // triangles by arithmetic; clear it after changing the mesh's triangles.
  bool gridMesh = false;

  // The direction toward a sun at this azimuth/altitude (true north) in this frame.
  Eigen::Vector3d towardSun(const SunPosition& sun) const;
};

// pixelSize: metres per pixel for a raster without CRS (0: refuse such a raster).
LocalFrame localFrame(const DemTerrain& dem, bool flat, double pixelSize = 0);

// Progress: fraction done in [0, 1] and a message; return false to cancel (then qota::Error).
using Progress = std::function<bool(double, const char*)>;

enum class Light : std::uint8_t { Shadow = 0, Lit = 1, NoData = 2 };

// The light at every pixel centre of the frame's grid, row-major. towardLight: unit vector toward
// the light in the frame. A light at or below the horizon (z <= 0) leaves every cell in shadow.
// threads: how many to test cells with; 0 = one per core.
// How shadowMask finds the triangles a cell's light ray may meet. Both give the same mask
// (tested on every cell); each candidate passes the shadow quadtree's exact test.
enum class ShadowSearch {
  // Strips one pixel wide along the sun's azimuth, each holding the occluding triangles it
  // meets sorted by distance along the azimuth; a ray searches its strip from its own cell on,
  // skipping blocks of triangles that cannot reach its height (shadow.cpp), and decides the rest
  // with mappedTriangleAbove (terrain.hpp), the index's test from the corners. No index and no
  // light-frame tree, whose build at a low sun (most of the terrain facing away from the light,
  // in long slivers) costs more than all the queries. Needs a sun not straight overhead (else
  // Quadtree).
  Strips,
  // The paper's shadow quadtree, built in the light's frame.
  Quadtree,
};
std::vector<Light> shadowMask(const LocalFrame& frame, const Eigen::Vector3d& towardLight,
                              const TerrainOptions& options = {}, const Progress& progress = {},
                              unsigned threads = 0, ShadowSearch search = ShadowSearch::Strips);

// How far (metres) a shadow can reach across the raster's edge: relief / tan(altitude).
double shadowReach(const LocalFrame& frame, const Eigen::Vector3d& towardLight);

}  // namespace qota
