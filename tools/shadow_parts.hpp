// What qota shadow's two ways of running share: the whole raster in memory (shadow.cpp) and by
// tiles (shadow_tiles.cpp). Internal to the tool.
#pragma once

#include <Eigen/Core>
#include <ostream>
#include <string>
#include <utility>
#include <vector>

#include "qota/instant.hpp"
#include "qota/shadow_frame.hpp"
#include "qota_tools.hpp"

namespace qota::tools {

// How near a pole east-north-up is taken as undefined (degrees of latitude: about a kilometre
// on the Earth, 60 m on the Moon): -az/-alt and --sun-vector there are refused.
constexpr double kPoleDegrees = 0.01;

struct LightChoice {
  Eigen::Vector3d toward;  // unit, frame coordinates
  std::string description;
};
// The light the options give (-az/-alt, --sun-vector, --time), seen from the frame's centre.
LightChoice chooseLight(const ShadowOptions& o, const LocalFrame& frame, std::ostream& out);
// --hours START END STEP of --time's date in --tz, checked.
LocalSpan hoursSpan(const ShadowOptions& o);
// GDAL's terminal progress ("0...10...20..."), scaled into [lo, hi] of the whole run; none when quiet.
Progress termProgress(bool quiet, double lo, double hi);
// Everything that can be refused before any work: the light, the values, the outputs.
void checkOptions(const ShadowOptions& o, const std::string& format);
// The most memory (bytes) the whole raster's shadows take in this process, from its resident
// memory now (measured rates per pixel, ShadowTiles::bytesPerWholePixel).
std::uint64_t wholeEstimate(const ShadowOptions& o, std::uint64_t resident);
// Whether the run goes by tiles: asked for (--tile-size, --tile), or the whole raster would not
// fit in o.maxMemory (or, without it, in the memory available).
bool runsByTiles(const ShadowOptions& o);
// What --fill-voids did, as outputs record it (QOTA_FILL_VOIDS).
inline constexpr const char* kFillVoidsText = "voids filled first by GDAL's fill-nodata, up to 100 pixels out";

// What a shadow or hours raster records of its making (QOTA_TOOL, QOTA_SOURCE, QOTA_BAND,
// QOTA_FRAME, QOTA_LIGHT, QOTA_TIME, QOTA_TZ, QOTA_HOURS, QOTA_VALUES); withProvenance adds the
// version and command line.
std::vector<std::pair<std::string, std::string>> shadowProvenance(const ShadowOptions& o, int band,
                                                                  const std::string& frame, const std::string& light);
// True when both paths name the same existing file (or the same path).
bool sameFile(const std::string& a, const std::string& b);
// --mapping read by the registry's flags: a map mapping (cartesian) is flat, one whose heights are
// over the ellipsoid (geodetic) the default, which `flat` contradicts; the others are refused,
// the message ending with `others` (what the mapping cannot do for this tool).
bool flatByMapping(const std::string& mapping, bool flat, const char* tool, const char* others);
// How the run's options place the DEM in its frame (--flat, --pixel-size, -z, -s, --height-ref).
FrameOptions frameOptionsOf(const RasterJobOptions& o);
// Refuses a raster of more pixels than --max-pixels, with the time it would take (whole or by tiles).
void refuseBeyondMaxPixels(const ShadowOptions& o, const DemTerrain& described);
// The run by tiles (shadow_tiles.cpp): memory bounded by o.maxMemory, output streamed.
int shadowByTiles(const ShadowOptions& o, const std::string& format, std::ostream& out, std::ostream& err);

}  // namespace qota::tools
