// What a DEM's heights are measured from (its vertical reference), and the geoid undulation N
// that turns a height H over a geoid into a height h = H + N over the ellipsoid: what qota adds
// wherever a height becomes geometry on an ellipsoid (the geodetic mapping, shadows and sunlight
// hours on the ellipsoid). Maps (the Cartesian mapping, --flat) keep the raster's heights as they
// are.
//
// The reference, in this order:
// - asked: --height-ref (height_ref= in Python): "ellipsoid", "egm96", "egm2008", "crs" (the
//   raster's own vertical CRS, which must then be stated), "radius:R" (heights over a sphere of
//   radius R metres, on a body whose CRS is a sphere: MOLA's convention) or the path of a grid;
// - stated by the raster: a compound CRS (EPSG:4326+5773: EGM96 height; +3855: EGM2008 height),
//   a vertical CRS in its metadata, or a three-dimensional geographic CRS (EPSG:4979: heights over
//   the ellipsoid);
// - assumed, and said so: over the EGM96 geoid on the Earth (SRTM's, and most global DEMs'
//   reference; the nearest of the two on the others), over the body's ellipsoid elsewhere.
// Geoids are grids of N in metres over longitude/latitude: EGM96 is PROJ's egm96_15.gtx
// (Debian's proj-data); EGM2008 is us_nga_egm08_25.tif (not packaged: `projsync --file
// us_nga_egm08_25.tif`); any GDAL raster of undulations (an areoid for Mars) by its path. A grid
// that is not found is an error, never a silent zero. Between grid nodes N is bilinear, as PROJ's
// vgridshift interpolates it, the longitude wrapped on a grid that spans 360 degrees.
#pragma once

#include <memory>
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "qota/dem.hpp"

namespace qota {

struct HeightReference {
  std::string name = "ellipsoid";  // "ellipsoid", "EGM96 geoid", "EGM2008 geoid", or a grid's file name
  // The geoid grid's path; "radius:R" for a sphere of radius R metres on a spherical body (MOLA's
  // "topography = radius - 3396000 m": a constant undulation R - a); empty: over the ellipsoid.
  std::string grid;
  std::string why;       // "stated by its vertical CRS EGM96 height (EPSG:5773)", ...
  bool assumed = false;  // neither stated nor asked
  bool ellipsoidal() const { return grid.empty(); }
  // "EGM96 geoid (egm96_15.gtx; assumed: the raster states no vertical reference)"
  std::string describe() const;
};

// The reference of `dem`'s heights (above). asked: the option's text, or "" for the raster's own
// (else assumed). Throws qota::Error naming what is missing: an unknown option, a grid that is
// not found, a vertical CRS qota knows no geoid grid for ("crs" asked of a raster that states
// none).
HeightReference heightReferenceOf(const DemTerrain& dem, const std::string& asked);

// A reference as a tree file records it (its name and grid path): the grid found where it was,
// or by its file name in PROJ's folders. Throws qota::Error when it is not found here.
HeightReference storedHeightReference(const std::string& name, const std::string& grid);

// The option's words, for help and messages.
inline constexpr const char* kHeightRefChoices = "ellipsoid, egm96, egm2008, crs, radius:R, or a grid file";

// A geoid grid in memory (a few megabytes for EGM96's 15-minute grid), or none (the ellipsoid).
class Geoid {
 public:
  Geoid() = default;  // the ellipsoid: N = 0
  // Throws qota::Error naming the grid when GDAL cannot read it as longitude/latitude.
  explicit Geoid(const HeightReference& reference);
  // Only the nodes over a box of longitudes and latitudes (degrees, lon0 <= lon1 and lat0 <= lat1;
  // lon1 may pass 180), with two nodes of margin: what a raster's frame needs, a few kilobytes
  // instead of EGM96's whole grid. undulation() is NaN beyond the window.
  Geoid(const HeightReference& reference, const std::array<double, 4>& lonLatBox);
  // The bytes its grid holds.
  std::uint64_t bytes() const { return values_.size() * sizeof(float); }
  bool ellipsoidal() const { return values_.empty() && constant_ == 0; }
  // N in metres at (lon, lat) degrees; NaN outside a grid that covers part of the body.
  double undulation(double lon, double lat) const;
  // The least and greatest N over the box [lon0, lon1] x [lat0, lat1] (degrees; lon1 may pass
  // 180): the grid nodes around it, which bound every value interpolated inside.
  std::pair<double, double> rangeOver(double lon0, double lat0, double lon1, double lat1) const;

 private:
  double node(long long col, long long row) const;
  std::string path_;
  void read(const std::optional<std::array<double, 4>>& lonLatBox);
  int width_ = 0, height_ = 0;     // the whole grid's nodes
  long long col0_ = 0, row0_ = 0;  // the window read: its first node
  long long windowWidth_ = 0, windowHeight_ = 0;
  double lon0_ = 0, lat0_ = 0, dlon_ = 1, dlat_ = -1;  // the first node's centre and the steps
  bool wraps_ = false;
  std::vector<float> values_;
  double constant_ = 0;  // a sphere's undulation over a spherical body (radius:R)
};

}  // namespace qota
