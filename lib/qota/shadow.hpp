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
// Frame (LocalFrame): the DEM in metres, east-north-up at its centre. A DEM with a CRS is put on
// its ellipsoid (WGS84 unless the CRS says otherwise; Mars's, the Moon's...): every pixel centre
// at its longitude, latitude (through PROJ for a projected CRS) and height, in geocentric
// coordinates turned to east-north-up at the centre. So the Earth's curvature lowers distant
// terrain as it should, and the light, one direction in that frame (parallel rays: the sun is far
// away), meets each cell at the sun's own azimuth and altitude there: on a continent or the whole
// globe the terminator falls where it is. Rays are straight lines in that frame. A raster that
// spans 360 degrees of longitude is closed at the antimeridian, and at the poles when its rows
// reach within a pixel of them (raster_grid.hpp), so no ray slips through a seam. `flat` maps a
// geographic DEM's longitude and latitude linearly, and a projected DEM's grid as it is in metres
// (the sun's azimuth turned from true north to grid north); a raster without CRS is a pixel grid
// of `pixelSize` metres. Heights are converted to metres from the raster's vertical unit
// (dem.hpp), times `zFactor`.
//
// The outer half pixel: the frame's surface reaches the raster's edge, flat across it (the same
// rule as sampling, raster_grid.hpp), so that terrain occludes. Cells are still the pixel centres.
//
// The body: a cell whose ray toward the light passes below the lowest terrain of the DEM (less a
// margin for the chords between pixel centres), on the ellipsoid, is in shadow: the planet itself
// is in the way, whatever lies beyond the raster. In a flat frame that is a light at or below the
// horizon.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "qota/dem.hpp"
#include "qota/raster_grid.hpp"
#include "qota/sun.hpp"
#include "qota/terrain.hpp"

namespace qota {

// How a DEM becomes a frame (see above).
struct FrameOptions {
  bool flat = false;      // no curvature: lon/lat scaled linearly, a projected grid as it is
  double pixelSize = 0;   // metres per pixel for a raster without CRS (0: refuse such a raster)
  double zFactor = 1;     // heights times this (gdaldem's -z), after the unit's conversion
  // gdaldem's -s: horizontal units per vertical unit, for a raster whose vertical unit is not
  // known (0: metres). Horizontal units: the CRS's linear unit, a degree counted as 111120 m
  // (gdaldem's convention), or the metre of --pixel-size for a raster without CRS.
  double scale = 0;
};

// The DEM's vertices in a local metric east-north-up frame (same vertex indices as dem.mesh for
// the cells), with every cell's two triangles and the closure's (border, seam, caps). Voids are
// filled from their rims for occlusion: light cannot pass under the terrain through missing data,
// and every vertex has a full ring of triangles. Their cells stay nodata (valid = 0) in every
// output.
struct LocalFrame {
  Mesh mesh;                        // cells first (vertex i = cell i), then grid's extra vertices
  std::vector<std::uint8_t> valid;  // per cell: the DEM has a height here
  int width = 0, height = 0;
  bool geographicLocation = false;  // centreLon/Lat are known (the DEM has a CRS)
  double centreLon = 0, centreLat = 0;
  // Clockwise angle (degrees) from the frame's +y axis to true north: 0 for east-north-up
  // frames, the meridian convergence for flat projected grids.
  double trueNorthFromY = 0;
  double minHeight = 0, maxHeight = 0;  // metres above the reference surface, over valid cells
  double pixelSizeX = 1, pixelSizeY = 1;  // metres, at the centre
  double metresPerUnit = 1;             // of the DEM's heights (unit and zFactor)
  std::string description;
  // The triangulation: mesh's triangles are grid's (inner ones in the DEM's order, then the
  // closure's), so the shadow mask finds a vertex's triangles by arithmetic. Clear gridMesh after
  // changing the mesh's triangles.
  RasterGrid grid;
  bool gridMesh = false;
  // +1 when grid's corner order turns counter-clockwise seen from above (the body's up), -1 when
  // clockwise: the same for every triangle of the grid and its closure.
  int gridWinding = 1;
  // The body the DEM lies on. For an ellipsoid (semi-axes a, b), a frame point p is the
  // geocentric point rotation^T p + origin (rotation: geocentric to east-north-up at the centre).
  struct Body {
    std::string name = "Earth";  // the CRS's celestial body ("" without CRS)
    bool ellipsoid = false;      // false: a flat frame, "up" is +z everywhere
    double a = 0, b = 0;
    Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
    Eigen::Vector3d origin = Eigen::Vector3d::Zero();
    double lowest = 0;  // the height (metres) below which a ray is in the body (see above)
  } body;

  std::size_t cellCount() const { return static_cast<std::size_t>(width) * height; }
  // The unit upward normal of the body at frame point p ((0, 0, 1) in a flat frame).
  Eigen::Vector3d upAt(const Eigen::Vector3d& p) const;
  // How far (degrees) the light may be below the horizon at the centre while some cell may still
  // see it: the largest angle between the centre's up and a cell's, plus the dip of the horizon
  // from the highest cell down to body.lowest. 0 in a flat frame. (A pass over the cells.)
  double horizonSlack() const;
  // Whether the ray from p toward `light` passes into the body (below body.lowest).
  bool rayEntersBody(const Eigen::Vector3d& p, const Eigen::Vector3d& light) const;
  // The direction toward a sun at this azimuth/altitude (true north) seen from the DEM's centre,
  // in this frame.
  Eigen::Vector3d towardSun(const SunPosition& sun) const;
};

// The body test of many rays toward one light (LocalFrame::rayEntersBody), set up once.
class BodyRays {
 public:
  BodyRays(const LocalFrame& frame, const Eigen::Vector3d& light);
  bool entersBody(const Eigen::Vector3d& p) const;

 private:
  const LocalFrame* frame_;
  Eigen::Vector3d light_, scale_ = Eigen::Vector3d::Ones(), k_ = Eigen::Vector3d::Zero();
  double k0_ = 0, qa_ = 0;
};

LocalFrame localFrame(const DemTerrain& dem, const FrameOptions& options);
// pixelSize: metres per pixel for a raster without CRS (0: refuse such a raster).
LocalFrame localFrame(const DemTerrain& dem, bool flat, double pixelSize = 0);

// The celestial body of a CRS ("Earth", "Mars", "Moon", ...; PROJ's name for its ellipsoid, or
// guessed from the semi-major axis); "" for no CRS.
std::string celestialBody(const std::string& crsWkt);

// Progress: fraction done in [0, 1] and a message; return false to cancel (then qota::Error).
using Progress = std::function<bool(double, const char*)>;

enum class Light : std::uint8_t { Shadow = 0, Lit = 1, NoData = 2 };

// The light at every pixel centre of the frame's grid (cellCount() entries, row-major).
// towardLight: vector toward the light in the frame. In a flat frame a light at or below the
// horizon (z <= 0) leaves every cell in shadow; on an ellipsoid each cell has its own horizon.
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
