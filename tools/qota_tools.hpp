// The qota command-line tools as library functions: each takes an options struct and streams and
// returns the process exit code, so tests call them directly and tools/main.cpp only parses
// arguments. Errors are printed to `err` as "qota <tool>: <message>".
#pragma once

#include <Eigen/Core>
#include <array>
#include <iosfwd>
#include <optional>
#include <string>
#include <vector>

#include "index_source.hpp"
#include "qota/shadow.hpp"
#include "qota/terrain.hpp"

namespace qota::tools {

// qota sample: terrain heights at points, one output line per input line. The source may also be
// a tree file (qota build) or, in the cartesian mapping, a mesh file.
//
// Input lines: "x y [fields...]" (the topmost terrain at x, y), or with queryZ "x y z
// [fields...]" (the nearest terrain at or below z), in the raster's CRS, or in `srs` when given
// (any string GDAL's SetFromUserInput takes: EPSG:4326, WKT, PROJ; coordinates in x =
// easting/longitude, y = northing/latitude order). Fields are separated by spaces, tabs or
// commas; the fields after the coordinates are passed through, unchanged, after the answer (as
// gdallocationinfo does from GDAL 3.9), behind the separator that followed the coordinates. A
// blank line gives a blank output line. With `header`, the first line is a header: it prints
// "height" (and "x y z" with printWorld) followed by its other names.
//
// Output lines: the height (shortest decimal that round-trips to the same double, or fixed with
// `precision` decimals) in the source's own vertical unit (the raster's, as gdallocationinfo
// prints it; a mesh's z), followed by the world point x y z when `printWorld`; "none" where there
// is no terrain (a hole, or off the raster); "error" for a malformed line. Between the outermost
// pixel centres and the raster's edge (the outer half pixel) the height is that of the nearest
// point on the outermost centres' lines (dem.hpp). Exit code: 0 when every line had a valid point
// on the raster, 1 when any line was malformed or off the raster (with a message naming the line
// on stderr), 2 for a usage error or unreadable file.
// The source as every tool reads one (qota::SourceOptions: the path, band, mapping and its
// parameters, --height-ref, --origin, the quadtree's options), and what sample adds: where the
// lines come from and go, and how they read and print. The mappings' lines (coords/README.md):
// cartesian "x y [z]" in the raster's CRS, answers the height in its vertical unit; spherical
// "lon lat [r]", the surface radius in metres; geodetic "lon lat [h]", the height along the
// ellipsoid normal in the raster's vertical unit; cylindrical "angle axial [h]", the distance
// from the axis in metres ("below" meaning away from it); enu "east north [up]" in metres in the
// frame at `origin`, the terrain's up in metres. (A base, not a member: a sample's options are a
// source's and these.)
struct SampleOptions : SourceOptions {
  std::string inputFile;   // empty: read from the `in` stream
  std::string outputFile;  // empty: write to the `out` stream; else written atomically
  std::string srs;         // CRS of the input points; empty: the raster's
  int precision = -1;      // -1: shortest round-trip; else decimals after the point (<= 100)
  bool printWorld = false;
  bool queryZ = false;  // the third field is the query height
  bool header = false;  // the first line is a header
  bool quiet = false;   // no notes on `err` (what was assumed); points' problems still are
  bool swapXY = false;  // input lines are "y x" (lat lon), as GeographicLib's -w
  // geodetic: heights read (--query-z) and printed are over the source's reference (heightRef)
  // unless this is "ellipsoid" (printed over the ellipsoid).
  std::string outputHeightRef = {};
  // How a raster's height at a point is found (qota/kernel_sampler.hpp): "triangle" (the exact
  // surface, the default), or GDAL's rules "nearest" (what gdallocationinfo prints), "bilinear",
  // "cubic"; these on a raster in the cartesian mapping only.
  std::string resampling = "triangle";
  // Points from a vector layer (qota/../tools/sample_vector.cpp): when inputFile opens as an OGR
  // layer with geometries (GeoPackage, GeoJSON, Shapefile, FlatGeobuf, ..., a CSV whose columns
  // name x and y (x, lon, long, longitude, easting; y, lat, latitude, northing) or hold WKT), its
  // points are sampled in the layer's CRS (srs when the layer states none) and written to
  // outputFile as a layer of any OGR format (by extension, or outputFormat): every input field
  // and geometry kept, a Real field `field` added (null where there is no terrain).
  std::string field = "height";
  std::string outputFormat = {};              // OGR driver of the output layer; empty: by extension
  std::string layer = {};                     // the input layer; empty: the first
  std::vector<std::string> openOptions = {};  // the input's open options NAME=VALUE (--oo)
};
int sample(const SampleOptions& options, std::istream& in, std::ostream& out, std::ostream& err);

// qota info: what a source is, one "name: value" per line (or one JSON object). A raster is
// described without building anything: driver, size, every band (type, unit, nodata, scale and
// offset; with `stats` the height range and void pixels, read by strips), the CRS, the vertical
// CRS and unit, what the heights are over on the ellipsoid, the extent (and in longitude/latitude),
// the pixel size on the ground, and the memory each tool would take. `tree` builds the quadtree
// too (in the source's mapping) and prints its statistics (the paper's Table 4), refusing what
// does not fit with the streaming tools named. A tree file or a mesh is read whole and its tree's
// statistics printed.
struct InfoOptions {
  // The source, as every tool reads one: a raster (in --mapping, default cartesian), a mesh or a
  // tree file; the band, the mapping's parameters and the quadtree's.
  SourceOptions source;
  bool quiet = false;  // (info prints no notes; kept so that -q means the same in every tool)
  bool tree = false;   // a raster: build the quadtree and print its statistics
  bool stats = false;  // a raster: read every pixel for each band's height range (gdalinfo's -stats)
  bool json = false;   // one JSON object, the keys the labels in snake case
};
int info(const InfoOptions& options, std::ostream& out, std::ostream& err);

// What qota shadow and qota viewshed share: a DEM in, a raster on its grid out, and how the DEM
// is placed in its frame (FrameOptions). (A base, not a member: a shadow's options are these and
// its light's.)
struct RasterJobOptions {
  std::string source;
  std::string output;
  std::string format;                        // GDAL driver; empty: guessed from the extension
  std::vector<std::string> creationOptions;  // NAME=VALUE
  bool quiet = false;
  int band = 0;  // 1-based; 0: the raster's only band
  bool flat = false;
  // The frame, as every tool's --mapping names it: "geodetic" (a DEM with a CRS on its
  // ellipsoid, the default) or "cartesian" (the grid flat: as `flat`); the other mappings are
  // refused by name. Empty: geodetic, or flat with `flat`.
  std::string mapping = {};
  double pixelSize = 0;  // metres per pixel for a raster without CRS
  double zFactor = 1;    // gdaldem's -z
  double scale = 0;      // gdaldem's -s (horizontal units per vertical unit)
  // On the ellipsoid: what the heights are over (FrameOptions::heightRef); recorded in the output.
  std::string heightRef = {};
  std::string png;  // a PNG preview over a hillshade
  // The DEM's voids filled first (DemOptions::fillVoids with kFillVoidsPixels): the pixels get
  // values too; recorded as QOTA_FILL_VOIDS. The whole raster in memory (not by tiles).
  bool fillVoids = false;
};

// qota shadow: where a directional light (the sun) is blocked by the terrain, as a raster on the
// DEM's grid (see qota/shadow.hpp for the geometry).
//
// The light: azimuth/altitude in degrees (gdaldem's -az/-alt), or a vector toward the light in
// the east-north-up frame at the DEM's centre, or an instant (the Sun's position seen from the
// DEM's centre, on the Earth or Mars; `time` is ISO 8601 with its UTC offset, or `tz` gives the
// zone: an offset or an IANA name, see qota/instant.hpp). Heights are converted to metres from the
// raster's vertical unit (band unit type or vertical CRS) times zFactor; scale (gdaldem's -s) is
// for rasters whose unit is not known.
// Output: Byte, litValue where lit, shadowValue in shadow, nodataValue (also set as the band's
// nodata) where the DEM has none (three different values); or, with hours, Float32 hours of
// direct sunlight (nodata -1): the elapsed time between the local clock times START and END of
// the date, in steps of STEP hours (at least a minute; the last may be shorter), a pixel lit at a
// step's middle counting the whole step. Written to a temporary file and renamed into place, so a
// failed or cancelled run never leaves a partial raster under the requested name; an output that
// is the input, or a format that stores no pixels (VRT), is refused. Exit code 0 on success, 2 on
// error.
struct ShadowOptions : RasterJobOptions {
  std::optional<double> azimuth, altitude;
  // -az/-alt are east-north-up at this (longitude, latitude) (default: the DEM's centre); refused
  // within kPoleDegrees of a pole, where east and north are undefined.
  std::optional<std::array<double, 2>> at;
  std::optional<Eigen::Vector3d> sunVector;
  // The direction to the Sun in the body-fixed, body-centred frame (SPICE's spkpos in IAU_MARS,
  // an ECEF vector), or the sub-solar point (east longitude, planetocentric latitude: the Sun's
  // declination): the same light anywhere on the body, poles included.
  std::optional<Eigen::Vector3d> sunVectorBody;
  std::optional<std::array<double, 2>> subsolar;
  // A point light at x, y (the raster's CRS) and z metres above the surface there, or over the
  // DEM's reference with lightPointAbsolute (qota/viewshed.hpp, pointLightMask); the whole raster
  // in memory, one mask.
  std::optional<std::array<double, 3>> lightPoint;
  bool lightPointAbsolute = false;
  std::string time;                            // ISO 8601
  std::string tz;                              // zone of a time without offset: +HH:MM or an IANA name
  std::optional<std::array<double, 3>> hours;  // start, end, step (local hours of the date)
  int litValue = 255, shadowValue = 0, nodataValue = 128;
  IndexOptions index;  // the quadtree's options (Maxpoly, Maxdepth) for a shadow search that builds one
  ShadowSearch search = ShadowSearch::Strips;  // how the occluders are found (same mask)
  // By tiles (qota/shadow_tiles.hpp; the same values as the whole raster's): memory bounded by
  // maxMemory bytes (0: three quarters of what is available), output streamed into a tiled
  // GeoTIFF or COG. Taken when the whole raster does not fit, or when tileSize is given: tiles
  // of tileSize pixels a side (0: the largest that fit), a multiple of 16. tile: only this tile
  // (column, row of the tile grid, from 0), written as a raster of its own, for batch
  // schedulers; qota assemble joins such tiles.
  std::uint64_t maxMemory = 0;
  // A raster of more pixels is refused before any work, with the time it would take (the pass
  // over 10^12 heights alone takes hours): raise it to run one that large.
  std::uint64_t maxPixels = 1ull << 32;
  int tileSize = 0;
  std::optional<std::array<int, 2>> tile;
  // By tiles: the pass over the heights (the height range and the frame, ShadowTiles::state)
  // read from this file when it exists (made for the same raster and frame options, else an
  // error), else made and written there, so that the jobs of a batch make it once.
  std::string tilesState;
};
int shadow(const ShadowOptions& options, std::ostream& out, std::ostream& err);

// qota viewshed: which pixels of a DEM an observer sees (qota/viewshed.hpp for the rule), as a
// Byte raster on the DEM's grid: visibleValue where the line of sight is clear, hiddenValue where
// terrain blocks it, nodataValue (also the band's nodata) where the DEM has none, outOfRangeValue
// beyond maxDistance (four different values; gdal_viewshed's 255 and 0 by default). The observer
// is given in the raster's CRS, or in `srs`; heights and the distance in metres. The DEM is placed
// as qota shadow places it (on its ellipsoid, or flat with `flat` / --mapping cartesian).
// Outputs staged and placed together (none on failure). Exit code 0 on success, 2 on error.
//
// Cumulative: with observersFile instead of observer, the count of the observers that see each
// pixel (UInt16, or UInt32 from 65535 observers on; nodata the type's largest value). The file is
// any OGR point layer (each feature's height from the field heightField when it has one; CSV with
// x/y, lon/lat or easting/northing columns) in its own CRS (one that states none, as a CSV, in
// `srs` or the raster's), or text lines "x y [height]" in `srs` or the raster's CRS.
struct ViewshedOptions : RasterJobOptions {
  std::optional<std::array<double, 2>> observer;  // x, y
  std::string observersFile;
  std::string heightField = "height";
  // With observersFile: also a raster of which observers see each pixel, bit k for the file's
  // k-th observer (Byte up to 7 observers, UInt16 up to 15, UInt32 up to 31; nodata the type's
  // largest value; the metadata names each bit's observer).
  std::string whichFile;
  std::string srs;            // CRS of the observer (and of text observers); empty: the raster's
  double observerHeight = 2;  // metres above the surface
  double targetHeight = 0;    // metres above each pixel's surface
  double maxDistance = 0;     // metres; 0: no limit
  double refraction = 0;      // coefficient k (qota/viewshed.hpp); one observer, on an ellipsoid
  int visibleValue = 255, hiddenValue = 0, nodataValue = 128, outOfRangeValue = 64;
  // Every pixel's line of sight through the quadtree, not the sweep (qota/viewshed.hpp; the same
  // answers, for comparison).
  bool perPixel = false;
  IndexOptions index;
};
int viewshed(const ViewshedOptions& options, std::ostream& out, std::ostream& err);

// qota assemble: tiles written by `qota shadow --tile` (or any rasters on one grid) joined into
// one raster: a GeoTIFF or COG streamed a tile at a time, or a VRT that points at the tiles. The
// tiles must share CRS, pixel size, data type and nodata, lie on one grid without overlapping,
// and (for qota's tiles, which say so in their metadata) be every tile of their run: a missing
// tile is an error naming it, never a hole. Exit code 0 on success, 2 on error.
struct AssembleOptions {
  std::vector<std::string> tiles;
  std::string output;
  std::string format;                        // GTiff, COG or VRT; empty: from the extension
  std::vector<std::string> creationOptions;  // NAME=VALUE
  bool quiet = false;
};
int assemble(const AssembleOptions& options, std::ostream& out, std::ostream& err);

// "64M", "2G", "1.5GiB", "300000000": bytes (K, M, G, T are powers of 1024). Throws qota::Error
// naming the text.
std::uint64_t parseByteSize(const std::string& text);

// qota render-tree: a picture of the QOTA quadtree over a DEM (the paper's Figure 4), as a grey
// PNG on the raster's own pixel grid scaled to `size` pixels on the long side (north up for a
// north-up raster; not georeferenced).
//
// Each leaf is filled with a grey level by its polygon count n: 255 (white) when empty, then
// darker on a log scale, 255 - 95 log(1 + n) / log(1 + Maxpoly), down to 160 at Maxpoly
// polygons; leaves holding more (at Maxdepth, or where no cut parts the polygons) stay at 160.
// The terrain shows through as a faint hillshade (Lambert, light from azimuth 315, altitude 45),
// which scales a fill by 0.65 (facing away) to 1 (facing the light); nodata pixels are not shaded.
// Leaf edges (and the edge of the tree's root box) are 1 pixel wide, grey 40, darker than any
// fill, so leaves smaller than a pixel merge into that grey. Written to a temporary file and
// renamed into place. Exit code 0 on success, 2 on error (unreadable DEM, output folder missing
// or not writable, output not named .png, size outside 16..16384).
struct RenderTreeOptions {
  SourceOptions source;  // as every tool reads one (a raster in --mapping, a mesh, a tree file)
  std::string output;
  int size = 1024;  // pixels along the image's long side
  // The depth drawn: nodes deeper are drawn as their ancestor at this depth; -1: the deepest whose
  // cells are 8 image pixels or more across.
  int depth = -1;
  bool quiet = false;
};
int renderTree(const RenderTreeOptions& options, std::ostream& out, std::ostream& err);

// qota build: the index of a terrain, built once and written as a tree file (treefile.hpp), which
// `qota sample`, `qota info` and `qota render-tree` then take in place of the terrain. The source
// is a raster or a mesh file in any mapping (index_source.hpp). Prints the tree's size and the
// build and write times unless quiet. Exit code 0, or 2 on error (nothing is left under the
// output name).
struct BuildOptions {
  SourceOptions source;
  std::string output;
  bool quiet = false;
};
int build(const BuildOptions& options, std::ostream& out, std::ostream& err);

// The whole qota command: parses argv (argv[0] is the program's name) and runs the subcommand.
// Never throws: every failure is a message on `err` and exit code 2.
// `qota --version`: qota's version and those of GDAL and PROJ it runs with and of GeographicLib
// it was built with, one "name version" per line.
std::string versionText();
// The command line qota was run with, as a shell would take it back (runCli records it; empty
// when a tool is called as a function): the provenance rasters carry (QOTA_COMMAND).
std::string commandLine();
void recordCommandLine(int argc, const char* const* argv);

int runCli(int argc, const char* const* argv, std::istream& in, std::ostream& out, std::ostream& err);

}  // namespace qota::tools
