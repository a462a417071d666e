// Viewsheds: which pixels of a DEM an observer sees, exactly, on the triangulated terrain.
//
// Rule: a pixel is visible when the open segment from the observer, at (x, y) and `observerHeight`
// metres above the surface there, to the pixel centre `targetHeight` metres above its surface
// meets no terrain strictly between its ends. The surface is the DEM's triangulated terrain (what
// `qota sample` answers: the pixel centres, two triangles a square, the outer half pixel flat to
// the raster's edge); triangles with a corner on a void are holes, which block nothing. "Above"
// is along the body's up (the ellipsoid normal), and the segment is straight in the frame
// (shadow_frame.hpp): on an ellipsoid, a straight line in geocentric coordinates through terrain
// placed by longitude, latitude and height, so the body's curvature is exact, not a correction
// term; in a flat frame (FrameOptions::flat) a straight line over the grid as it is.
//
// The test of a segment against a triangle is the planar index's exact side test
// (CartesianIndex::segmentMeets): a segment touching an edge or a corner is blocked, one that
// runs within the plane of a triangle grazes it (its neighbours decide: a flat plain seen from
// the ground is visible). A target on the surface (targetHeight 0) is a vertex of the terrain,
// whose own triangles meet its segment only there; an observer on the surface (observerHeight 0)
// is not blocked by the triangles it stands on.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "qota/dem.hpp"
#include "qota/shadow.hpp"
#include "qota/shadow_frame.hpp"

namespace qota {

enum class Sight : std::uint8_t { Hidden = 0, Visible = 1, NoData = 2, OutOfRange = 3 };

struct ViewshedOptions {
  double observerX = 0, observerY = 0;  // in the DEM's CRS (its world x, y; longitude, latitude)
  double observerHeight = 2;            // metres above the surface at the observer
  double targetHeight = 0;              // metres above each pixel centre's surface
  // Pixels farther than this (metres, horizontally: in the plane square to the observer's up)
  // are OutOfRange and not tested; 0: no limit.
  double maxDistance = 0;
  // Refraction coefficient k (0.13 is the usual one for the Earth's atmosphere; 0: straight
  // lines): a line of sight bends toward the body with curvature k / R, modelled as every terrain
  // point raised by k d^2 / (2 R) (d: its distance from the observer seen from above, R the body's
  // mean radius), which is straight lines over a body of radius R / (1 - k). On an ellipsoid only.
  double refraction = 0;
  FrameOptions frame;  // flat or on the ellipsoid, units, the heights' reference
  IndexOptions index;  // the quadtree's options
  // Decide lines of sight by the exact sweep where it applies (a flat frame, an observer above
  // the surface and inside the outermost pixel centres), testing one by one only the pixels it
  // leaves undecided; on an ellipsoid (an observer above the surface, a pixel or more inside the
  // outermost centres) walk each line of sight over the squares under it, with no quadtree to
  // build; false: every pixel's line of sight through the quadtree. The same answers.
  bool sweep = true;
};

struct Viewshed {
  std::vector<Sight> sight;  // per pixel, row-major
  Eigen::Vector3d observer;  // in the frame
  double surface = 0;        // the terrain's height under the observer, metres over the DEM's reference
  std::size_t visible = 0, tested = 0;
  // Of the tested pixels: decided by the sweep, and tested one by one (by the sweep's exact
  // fallback, or all of them without the sweep).
  std::size_t swept = 0, oneByOne = 0;
  // How those were tested: "walk" (the squares under each line of sight: the sweep's exact
  // fallback, and on an ellipsoid), or "quadtree" (ViewshedOptions::sweep off, or an observer
  // neither takes: on the surface, within a pixel of the outermost centres, a raster round the
  // globe or one too far from flat to walk).
  std::string method;
  std::string frameDescription;
};

// Throws qota::Error naming the value for an observer off the raster or over a void, heights or
// a distance that are not finite or negative, a raster smaller than 2 x 2 pixels.
// threads: 0 = one per core (at most 8).
Viewshed viewshed(const DemTerrain& dem, const ViewshedOptions& options, const Progress& progress = {},
                  unsigned threads = 0);
// The same, taking the DEM's heights over instead of copying them (a raster of doubles less, and
// the time to fill it): dem.heights is left empty (its size, geotransform and CRS stay), and a
// DEM without heights is refused by every call that needs them.
Viewshed viewshed(DemTerrain&& dem, const ViewshedOptions& options, const Progress& progress = {},
                  unsigned threads = 0);

// Cumulative viewsheds: how many of a list of observers, each with its own height, see each
// pixel (the same rule). The DEM is placed and indexed once for all of them.
struct Observer {
  double x = 0, y = 0;  // in the DEM's CRS
  double height = 2;    // metres above the surface
  std::string name;     // for errors ("points.txt:12"); empty: "observer K"
};
struct CumulativeOptions {
  double targetHeight = 0;  // metres above each pixel centre's surface
  double maxDistance = 0;   // metres, horizontally from each observer; 0: no limit
  // Also which observers see each pixel, a bit each (observer k: bit k); at most kMaxWhich.
  bool which = false;
  FrameOptions frame;
  IndexOptions index;
  bool sweep = true;  // as ViewshedOptions::sweep, for each observer
};
constexpr std::size_t kMaxWhich = 64;
struct CumulativeViewshed {
  std::vector<std::uint32_t> count;  // per pixel, row-major: the observers that see it
  std::vector<std::uint64_t> which;  // per pixel, with CumulativeOptions::which: bit k, observer k sees it
  std::vector<std::uint8_t> valid;   // per pixel: the DEM has a height here
  std::string frameDescription;
};
// Throws qota::Error naming the observer (its name) that is off the raster or over a void.
CumulativeViewshed cumulativeViewshed(const DemTerrain& dem, std::span<const Observer> observers,
                                      const CumulativeOptions& options, const Progress& progress = {},
                                      unsigned threads = 0);

// Shadows of a point light (a lamp, a lander's floodlight): the paper's spherical mapping centred
// on the light, done as lines of sight. A pixel centre is in shadow when the open segment from it
// to the light meets terrain (its own triangles left out: they meet the segment only at the pixel),
// or when the light arrives from below its own surface (attached shadow, as shadow.hpp says);
// else lit. Voids are filled from their rims, as for the sun (light cannot pass under the
// terrain); their pixels are NoData. The light at world (x, y) (the DEM's CRS; off the raster
// too when its height is absolute), `height` metres above the surface there when aboveSurface,
// else over the DEM's reference (its ellipsoid or geoid, FrameOptions::heightRef).
struct PointLightOptions {
  double x = 0, y = 0, height = 0;
  bool aboveSurface = true;
  FrameOptions frame;
  IndexOptions index;
  // Walk each pixel's segment to the light over the squares under it, where the light stands
  // inside the outermost pixel centres' lines (no quadtree to build); false: through the
  // quadtree. The same answers.
  bool walk = true;
};
std::vector<Light> pointLightMask(const DemTerrain& dem, const PointLightOptions& options,
                                  const Progress& progress = {}, unsigned threads = 0);

}  // namespace qota
