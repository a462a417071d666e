// Terrains from elevation rasters, through GDAL: any raster GDAL reads (GeoTIFF, SRTM .hgt, USGS
// ASCII DEM, DTED, ...).
//
// Geometry: the band asked for (DemOptions::band; a raster with several bands must name one),
// scaled by the band's scale and offset when it has them. One vertex at every pixel centre, at world position
//     x = gt[0] + (col + 0.5) gt[1] + (row + 0.5) gt[2]
//     y = gt[3] + (col + 0.5) gt[4] + (row + 0.5) gt[5]
//     z = value
// in the raster's CRS units (the full geotransform, rotated ones too). Each cell (the square
// between four pixel centres) is split into two triangles along the diagonal from its top-left
// centre (col, row) to its bottom-right centre (col + 1, row + 1): (TL, BL, BR) and (TL, BR, TR).
// The surface therefore spans the pixel centres (the outer half pixel: below).
//
// Nodata: a pixel equal to the band's nodata value, or NaN or infinite, has no vertex height;
// every triangle touching it is left out, so nodata makes holes.
//
// The outer half pixel (between the outermost pixel centres and the raster's edge) has no
// triangles. A point there takes the height of the nearest point on the outermost pixel centres'
// lines (surfacePoint below): the surface is extended flat across the edge, as texture clamping
// does, so two tiles that share an edge both answer up to it. Sampling, shadows and tree files
// built from rasters all keep this rule.
//
// Units: heights stay in the raster's own vertical unit (what gdallocationinfo prints); the unit
// is read from the band's unit type ("m", "ft", "US survey foot", ...) or else from a vertical
// CRS, and DemTerrain::metresPerUnit converts it for geometry (shadows, curved worlds). A raster
// that says nothing is taken as metres.
//
// Frame: the Cartesian mapping with gravity -Z and its origin at the raster's centre (so UTM
// coordinates in the millions keep full precision in the index). The CRS (WKT) is kept with the
// terrain; coordinates are never reprojected here. A raster in longitude/latitude degrees is
// refused as a Cartesian terrain unless DemOptions::lonLatAsCartesian is set: its x and y would
// be degrees and its z metres, so slopes, normals and poses would be meaningless (heights alone
// are still right). Use loadOnEllipsoid (globe.hpp) for a metric frame, or reproject the raster.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "qota/cartesian.hpp"
#include "qota/memory_budget.hpp"
#include "qota/mesh.hpp"

namespace qota {

struct DemOptions {
  // 1-based band; 0: the raster's only band (a raster with several is refused: name one).
  int band = 0;
  // Memory the job may use; 0 means the memory available on this machine. A raster whose
  // terrain and what is built on it (`then`) would need more is refused before anything large is
  // allocated.
  std::uint64_t memoryLimitBytes = 0;
  // Accept a raster in longitude/latitude as a Cartesian terrain (x, y in degrees). Right for
  // heights at points (qota sample), wrong for anything metric (normals, slopes, poses, moves).
  bool lonLatAsCartesian = false;
  // What the caller builds on the terrain, for the memory check (qota/memory_budget.hpp): by
  // default a CartesianIndex with its quadtree.
  memory::PerItem then = memory::kCartesianIndex;
  // The same for a raster without CRS, when that differs (a viewshed sweeps its flat frame).
  std::optional<memory::PerItem> thenWithoutCrs = {};
  // On an ellipsoid (loadOnEllipsoid): what the heights are over (qota/geoid.hpp: "ellipsoid",
  // "egm96", "egm2008", "crs", a grid's path; "": the raster's own, else assumed). Maps ignore it.
  std::string heightRef = {};
  // Voids filled before the terrain is made (loadDem only, the whole raster in memory): GDAL's
  // fill-nodata (gdal_fillnodata: inverse distance weighting from the void's rim, searching this
  // many pixels out; what is farther from any data stays a void). 0: voids stay holes.
  double fillVoids = 0;
  // The grid's triangles in the terrain's mesh (loadDem); false: its vertices only, for callers
  // that triangulate the grid themselves (viewsheds and shadows place their own frame), saving
  // the time and memory of two triangles a pixel.
  bool triangles = true;
  // false: no vertices either (and so no triangles), the heights alone in DemTerrain::heights, a
  // third of the vertices' memory (viewsheds place their own frame from the heights).
  bool vertices = true;
};

// The search distance `--fill-voids` takes (gdal_fillnodata's default), in pixels.
inline constexpr double kFillVoidsPixels = 100;

// The vertical unit of a raster's heights.
struct VerticalUnit {
  std::string name;          // as the raster gives it ("metre", "ft", ...); "" when it says nothing
  double metresPerUnit = 1;  // 1 when it says nothing (metres assumed)
  bool known() const { return !name.empty(); }
};

// The unit a unit-type text names ("m", "metre", "ft", "foot", "US survey foot", "cm", ...), in
// metres; std::nullopt for a text that is not a length unit.
std::optional<double> metresPerLengthUnit(const std::string& unitText);

// What the raster says of its heights' reference (qota/geoid.hpp resolves it): a vertical CRS
// (alone or in a compound CRS), or a three-dimensional geographic CRS (heights over the
// ellipsoid), or nothing; and whether its CRS's ellipsoid is the Earth's.
struct VerticalReference {
  std::string name;          // the vertical CRS's name ("EGM96 height"); "" when it states none
  int epsg = 0;              // its EPSG code, 0 when unknown
  bool ellipsoidal = false;  // a geographic 3D CRS: heights over the ellipsoid, stated
  bool earth = true;         // the CRS's ellipsoid is the Earth's (or there is no CRS)
};

struct DemTerrain {
  std::string path;
  std::string driver;  // GDAL driver short name
  int width = 0, height = 0;
  std::array<double, 6> geotransform{0, 1, 0, 0, 0, 1};
  std::string crsWkt;  // empty when the raster has no CRS
  std::optional<double> nodata;
  std::uint64_t nodataPixels = 0;  // voids left (after DemOptions::fillVoids)
  std::uint64_t filledPixels = 0;  // voids DemOptions::fillVoids filled
  int band = 1;                    // the band read (1-based)
  // The band holds whole numbers (an integer data type, no scale or offset): heights between
  // pixel centres are interpolated from integers (qota sample prints them without the last-bit
  // noise of that arithmetic).
  bool integerValues = false;
  std::uint64_t estimatedBytes = 0;     // the job's peak memory as loadDem estimated it
  VerticalUnit verticalUnit;            // of the heights in mesh (they are kept in this unit)
  VerticalReference verticalReference;  // what the raster states of its heights' reference
  // A north-up grid in longitude/latitude degrees: a longitude names a meridian whatever its turn,
  // so onRaster and surfacePoint take x at whichever of x + 360 k lies on the raster (a MOLA grid
  // in 0..360 east answers -9.8 as 350.2; a tile across the antimeridian answers -179.8).
  bool lonLat = false;
  Mesh mesh;  // vertex index = row * width + col
  // With DemOptions::vertices false: the pixels' heights, row-major, NaN at voids (mesh empty).
  std::vector<double> heights;
  // Pixel i's height (NaN at a void), from the mesh or the heights.
  double heightOf(std::size_t i) const { return heights.empty() ? mesh.vertices[i].z() : heights[i]; }
  CartesianMapping mapping;  // gravity -Z, origin at the raster centre

  // World (x, y) of the centre of pixel (col, row).
  std::array<double, 2> pixelCentre(double col, double row) const {  // (inline: once a pixel)
    const auto& g = geotransform;
    return {g[0] + (col + 0.5) * g[1] + (row + 0.5) * g[2], g[3] + (col + 0.5) * g[4] + (row + 0.5) * g[5]};
  }
  // Fractional pixel coordinates (col, row) of a world point (col, row in [0, width] x [0, height]
  // on the raster).
  std::array<double, 2> pixelOf(double x, double y) const;
  // The same with the inverse geotransform computed once (inverseGeotransform()), for callers
  // that convert many points; the same bits.
  std::array<double, 6> inverseGeotransform() const;
  std::array<double, 2> pixelOf(double x, double y, const std::array<double, 6>& inverse) const {
    return {inverse[0] + x * inverse[1] + y * inverse[2], inverse[3] + x * inverse[4] + y * inverse[5]};
  }
  // True when the world point lies on the raster's footprint.
  bool onRaster(double x, double y) const;
  // x moved by whole turns of 360 degrees onto the raster's longitudes when it is a lonLat grid
  // and some turn is on it (else x as it is).
  double turnedOnto(double x) const;
  // The point whose height answers for (x, y) under the outer half-pixel rule: (x, y) itself
  // between the outermost pixel centres, else the nearest point on their lines (the pixel
  // coordinates clamped to [0.5, size - 0.5], converted back with the geotransform's own
  // arithmetic, so a clamped point lies exactly on the centres' line of a north-up raster).
  // std::nullopt off the raster.
  std::optional<std::array<double, 2>> surfacePoint(double x, double y) const;
  std::optional<std::array<double, 2>> surfacePoint(double x, double y, const std::array<double, 6>& inverse) const;
  // The frame of loadDem's terrain: gravity -Z, origin at the raster's centre, z = 0.
  CartesianMapping centredMapping() const;
};

// The geometry of a raster, without reading its pixels: size, geotransform, CRS, band, nodata,
// vertical unit. The same checks as loadDem (the file opens as a raster, the band exists).
DemTerrain describeDem(const std::string& path, const DemOptions& options = {});

// Whether a CRS (WKT) is geographic (longitude/latitude); false for none or one GDAL cannot read.
bool crsIsGeographic(const std::string& wkt);

// Reads a raster into a terrain. Throws qota::Error naming the file when it cannot be opened, has
// no such band (or several and none was named), has a unit type that is not a length, is in
// longitude/latitude without lonLatAsCartesian, or is too large for the memory limit.
DemTerrain loadDem(const std::string& path, const DemOptions& options = {});

// A raster open for reading windows of heights, for work that never holds the whole raster
// (RasterSampler, tiled jobs): the description (as describeDem, with `mapping` set as loadDem
// sets it, no mesh) and the heights of any window with loadDem's rule (the band's scale and
// offset applied; NaN for nodata, NaN, infinite or overflowing values). GDAL reads the blocks
// under the window through its block cache. One object per thread: reads are not thread-safe.
class DemWindows {
 public:
  DemWindows(const std::string& path, const DemOptions& options = {});
  ~DemWindows();
  DemWindows(const DemWindows&) = delete;
  DemWindows& operator=(const DemWindows&) = delete;

  const DemTerrain& dem() const { return dem_; }
  // Heights of pixels [col, col + w) x [row, row + h), row-major, into out. Throws qota::Error
  // naming the file for a window off the raster or a failed read.
  void read(int col, int row, int w, int h, std::vector<double>& out) const;

 private:
  struct Open;
  DemTerrain dem_;
  std::unique_ptr<Open> open_;
};

// Registers GDAL's drivers once; safe to call from anywhere.
void ensureGdalRegistered();

}  // namespace qota
