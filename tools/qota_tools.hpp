// The qota command-line tools as library functions: each takes an options struct and streams and
// returns the process exit code, so tests call them directly and tools/main.cpp only parses
// arguments. Errors are printed to `err` as "qota <tool>: <message>".
#pragma once

#include <iosfwd>
#include <string>

#include "qota/terrain.hpp"

namespace qota::tools {

// qota sample: terrain heights at points, one output line per input line.
//
// Input lines: "x y" (the topmost terrain) or "x y z" (the nearest terrain at or below z), in the
// raster's CRS, or in `srs` when given (any string GDAL's SetFromUserInput takes: EPSG:4326, WKT,
// PROJ; coordinates in x = easting/longitude, y = northing/latitude order). Numbers are separated
// by spaces, tabs or commas; a blank line gives a blank output line.
//
// Output lines: the height (shortest decimal that round-trips to the same double, or fixed with
// `precision` decimals), followed by the world point x y z when `printWorld`; "none" where there
// is no terrain (a hole, or off the raster); "error" for a malformed line. Exit code: 0 when every
// line had a valid point on the raster, 1 when any line was malformed or off the raster (with a
// message naming the line on stderr), 2 for a usage error or unreadable file.
struct SampleOptions {
  std::string source;       // raster path
  std::string inputFile;    // empty: read from the `in` stream
  std::string outputFile;   // empty: write to the `out` stream; else written atomically
  std::string srs;          // CRS of the input points; empty: the raster's
  int precision = -1;       // -1: shortest round-trip; else decimals after the point
  bool printWorld = false;
  TerrainOptions terrain;
};
int sample(const SampleOptions& options, std::istream& in, std::ostream& out, std::ostream& err);

// qota info: the raster, the terrain and the quadtree statistics (the paper's Table 4), one
// "name: value" per line.
struct InfoOptions {
  std::string source;
  TerrainOptions terrain;
};
int info(const InfoOptions& options, std::ostream& out, std::ostream& err);

}  // namespace qota::tools
