// The frame shadows are computed in (LocalFrame): a DEM's pixel centres, and the vertices that
// close its surface, in metres.
//
// The DEM in metres, east-north-up at its centre. A DEM with a CRS is put on
// its ellipsoid (WGS84 unless the CRS says otherwise; Mars's, the Moon's...): every pixel centre
// at its longitude, latitude (through PROJ for a projected CRS) and height, in geocentric
// coordinates turned to east-north-up at the centre. So the Earth's curvature lowers distant
// terrain as it should, and the light, one direction in that frame (parallel rays: the sun is far
// away), meets each pixel at the sun's own azimuth and altitude there: on a continent or the whole
// globe the terminator falls where it is. Rays are straight lines in that frame. A raster that
// spans 360 degrees of longitude is closed at the antimeridian, and at the poles when its rows
// reach within a pixel of them (raster_grid.hpp), so no ray slips through a seam. `flat` maps a
// geographic DEM's longitude and latitude linearly, and a projected DEM's grid as it is in metres
// (the sun's azimuth turned from true north to grid north); a raster without CRS is a pixel grid
// of `pixelSize` metres. Heights are converted to metres from the raster's vertical unit
// (dem.hpp), times `zFactor`.
//
// The outer half pixel: the frame's surface reaches the raster's edge, flat across it (the same
// rule as sampling, raster_grid.hpp), so that terrain occludes. Pixels are still the pixel centres.
//
// The body: a pixel whose ray toward the light passes below the lowest terrain of the DEM (less a
// margin for the chords between pixel centres), on the ellipsoid, is in shadow: the planet itself
// is in the way, whatever lies beyond the raster. In a flat frame that is a light at or below the
// horizon.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "qota/pixel_window.hpp"
#include "qota/dem.hpp"
#include "qota/geoid.hpp"
#include "qota/mesh.hpp"
#include "qota/raster_grid.hpp"
#include "qota/sun.hpp"

namespace qota {

// How a DEM becomes a frame (see above).
struct FrameOptions {
  bool flat = false;     // no curvature: lon/lat scaled linearly, a projected grid as it is
  double pixelSize = 0;  // metres per pixel for a raster without CRS (0: refuse such a raster)
  double zFactor = 1;    // heights times this (gdaldem's -z), after the unit's conversion
  // gdaldem's -s: horizontal units per vertical unit, for a raster whose vertical unit is not
  // known (0: metres). Horizontal units: the CRS's linear unit, a degree counted as 111120 m
  // (gdaldem's convention), or the metre of --pixel-size for a raster without CRS.
  double scale = 0;
  // What the heights are over, on an ellipsoid (qota/geoid.hpp: "ellipsoid", "egm96", "egm2008",
  // "crs", a grid's path; "": the raster's own, else assumed). Not used by flat frames.
  std::string heightRef = {};
  // Voids filled from their rims (fillVoids), so light cannot pass under the terrain; false leaves
  // them at the lowest height with data, for callers that drop the triangles that touch them
  // (viewsheds: voids are holes).
  bool fillVoids = true;
};

// The DEM's vertices in a local metric east-north-up frame (same vertex indices as dem.mesh for
// the pixels), with every cell's two triangles and the closure's (border, seam, caps). Voids are
// filled from their rims for occlusion: light cannot pass under the terrain through missing data,
// and every vertex has a full ring of triangles. Their pixels stay nodata (valid = 0) in every
// output.
struct LocalFrame {
  Mesh mesh;                        // pixels first (vertex i = pixel i), then grid's extra vertices
  std::vector<std::uint8_t> valid;  // per pixel: the DEM has a height here
  int width = 0, height = 0;
  bool geographicLocation = false;  // centreLon/Lat are known (the DEM has a CRS)
  double centreLon = 0, centreLat = 0;
  // Clockwise angle (degrees) from the frame's +y axis to true north: 0 for east-north-up
  // frames, the meridian convergence for flat projected grids.
  double trueNorthFromY = 0;
  double minHeight = 0, maxHeight = 0;    // metres above the reference surface, over valid pixels
  double pixelSizeX = 1, pixelSizeY = 1;  // metres, at the centre
  double metresPerUnit = 1;               // of the DEM's heights (unit and zFactor)
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

  // Where these pixels lie in the raster: the whole of it, or a window (windowFrame).
  PixelWindow window;

  std::size_t pixelCount() const { return static_cast<std::size_t>(width) * height; }
  // The unit upward normal of the body at frame point p ((0, 0, 1) in a flat frame).
  Eigen::Vector3d upAt(const Eigen::Vector3d& p) const;
  // How far (degrees) the light may be below the horizon at the centre while some pixel may still
  // see it: the largest angle between the centre's up and a pixel's, plus the dip of the horizon
  // from the highest pixel down to body.lowest. 0 in a flat frame. (A pass over the pixels.)
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

// A frame of one window of a raster, equal to the whole raster's frame on its pixels: the same
// origin, body, units, height range and vertex arithmetic, so each vertex has the whole frame's
// bits. A shadow computed in a window whose pixels reach far enough around a tile (shadow_tiles.hpp)
// is the whole raster's shadow on that tile. The surface is closed by the outer half pixel on
// every side of the window (on sides inside the raster that is terrain the whole raster does not
// have; shadow_tiles.hpp keeps it beyond the reach of any ray it tests).
//
// What every window shares, found without the raster's heights (frameBasis) and then from them
// (completeBasis: the height range of the valid pixels in metres, and a window's frame holding
// the centre square, whose vertices give the pixel size and the triangles' turn).
struct FrameBasis {
  DemTerrain raster;  // the raster's description (no mesh)
  FrameOptions options;
  // On an ellipsoid: the heights' reference and its geoid (none for the ellipsoid), whose least
  // and greatest undulation over the raster widen the height range (so that it bounds the
  // heights over the ellipsoid the frame places).
  HeightReference heightRef;
  std::shared_ptr<const Geoid> geoid;
  double geoidLow = 0, geoidHigh = 0;
  LocalFrame shared;            // the fields every window's frame copies (no mesh, pixels or grid)
  RasterGrid::Closure closure;  // the whole raster's
  bool geographic = false;
  double a = 0, flattening = 0;  // the CRS's ellipsoid
  bool complete = false;         // completeBasis was called
};
// Throws qota::Error as localFrame does (a CRS that cannot be read, a raster without CRS and no
// pixelSize, -z/-s out of range).
FrameBasis frameBasis(const DemTerrain& raster, const FrameOptions& options);
// Heights beyond this (metres, either way) are not terrain: a million kilometres is past the Moon.
// A raster's heights, an observer's, a target's and a light's are held to it: far beyond it
// the lines of sight's floating-point filters fail and every test goes to the exact predicates,
// hours for one raster.
inline constexpr double kMaxHeight = 1e9;
// Raw heights of `window` (row-major; NaN where no data) to metres in place, and which have data.
// Throws qota::Error naming the pixel for a height beyond kMaxHeight.
void heightsInMetres(const FrameBasis& basis, const PixelWindow& window, std::vector<double>& heights,
                     std::vector<std::uint8_t>& valid);
// The frame of `window`: heights in metres with the voids filled (fillVoids), valid per pixel.
// A raster closed round the globe has only the whole window. triangles: false leaves the mesh's
// triangles out (its vertices and the grid are there; grid.triangle(t) names any triangle's
// corners), for callers that read the triangulation from the grid (viewsheds).
LocalFrame windowFrame(const FrameBasis& basis, const PixelWindow& window, std::vector<double> heights,
                       std::vector<std::uint8_t> valid, bool triangles = true);
// The same over heights the caller keeps (a viewshed's over the whole raster: no copy of them),
// its points placed on up to `threads` threads (0: one per core; placeVertices).
LocalFrame windowFrame(const FrameBasis& basis, const PixelWindow& window, std::span<const double> heights,
                       std::vector<std::uint8_t> valid, bool triangles = true, unsigned threads = 1);
// The frame of `window` without its points (mesh empty; the grid, valid, body and units as
// windowFrame's), for callers that place the points they need on demand (FlatPlacement);
// placeVertices then adds them all, as windowFrame places them.
LocalFrame gridFrame(const FrameBasis& basis, const PixelWindow& window, std::vector<std::uint8_t> valid);
// threads: at most this many (0: one per core, up to 8), and a thread only for every 4 blocks
// of 65,536 points (each thread keeps its own buffers and CRS conversion). The same points
// whatever the threads.
void placeVertices(LocalFrame& frame, const FrameBasis& basis, std::span<const double> heights, unsigned threads = 1);
// Frame points of raster positions: pixel coordinates (GDAL's: pixel centres at + 0.5) and
// heights in metres over the frame's reference (the basis's heightRef on an ellipsoid), placed
// by the arithmetic windowFrame places its vertices with, so a pixel centre at its pixel's height
// is that vertex, bit for bit. pole: +1 / -1 for a point at the north / south pole (empty: none).
// Throws qota::Error naming the position where the CRS or the geoid cannot place it.
std::vector<Eigen::Vector3d> framePoints(const FrameBasis& basis, std::span<const double> col,
                                         std::span<const double> row, std::span<const double> height,
                                         std::span<const int> pole = {});
// A flat frame's placement (no body: FrameBasis::shared.body.ellipsoid false), which is one
// expression per point: framePoints places such frames' points through it, so a point placed
// here on demand is the frame's vertex, bit for bit. (A viewshed's sweep keeps no vertex array:
// 24 bytes a pixel it never needs whole.)
class FlatPlacement {
 public:
  explicit FlatPlacement(const FrameBasis& basis);  // throws qota::Error on a frame on an ellipsoid
  // The frame point at pixel position (col, row), `height` metres up.
  Eigen::Vector3d at(double col, double row, double height) const;
  // The same at a longitude and latitude (degrees) of a geographic raster (the poles' points).
  Eigen::Vector3d atLonLat(double lon, double lat, double height) const;
  bool lonLat() const { return kind_ == Kind::LonLat; }

 private:
  enum class Kind { Pixels, LonLat, Projected } kind_ = Kind::Pixels;
  double gt_[6] = {};
  double cc_ = 0, cr_ = 0, pixel_ = 1;                              // Pixels: the centre pixel, metres a pixel
  double centreX_ = 0, centreY_ = 0, unit_ = 1;                     // Projected: the centre, metres a CRS unit
  double lon0_ = 0, lat0_ = 0, nRad_ = 0, mRad_ = 0, cosLat0_ = 1;  // LonLat: radii of curvature at the centre
};
void completeBasis(FrameBasis& basis, double minHeight, double maxHeight, const LocalFrame& centre);
// localFrame(dem, options), and the basis it was made on (for framePoints).
// triangles: false leaves the mesh's triangles out, as windowFrame's (a hillshade's frame).
LocalFrame localFrame(const DemTerrain& dem, const FrameOptions& options, FrameBasis& basis, bool triangles = true);
// Copies what completeBasis found into a frame made before it.
void adoptBasis(LocalFrame& frame, const FrameBasis& basis);

// Fills NaN heights from their neighbours, rim inwards (onion peeling, as gdal_fillnodata does in
// spirit): each pass gives every void pixel next to known pixels the mean of those, until none is
// left. A window with no data at all becomes flat at 0. levels (optional): per pixel, the pass
// that filled it (0: had data; kNeverFilled: nothing to fill from). A pixel filled at pass L
// depends only on the pixels within L of it (Chebyshev distance), and its pass only on those
// within 2L: so a window's fill equals the whole raster's at every void pixel with 2L pixels of the
// window around it (or the raster's edge).
constexpr std::uint32_t kNeverFilled = 0xffffffffu;
void fillVoids(std::vector<double>& heights, int width, int height, std::vector<std::uint32_t>* levels = nullptr);
// pixelSize: metres per pixel for a raster without CRS (0: refuse such a raster).
LocalFrame localFrame(const DemTerrain& dem, bool flat, double pixelSize = 0);

// The celestial body of a CRS ("Earth", "Mars", "Moon", ...; PROJ's name for its ellipsoid, or
// guessed from the semi-major axis); "" for no CRS.
std::string celestialBody(const std::string& crsWkt);

}  // namespace qota
