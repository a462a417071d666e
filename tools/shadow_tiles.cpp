// qota shadow by tiles: a raster of any size in bounded memory (see qota/shadow_tiles.hpp for why
// every tile equals the whole raster's shadow there), streamed into a tiled GeoTIFF or COG.
#include <gdal_priv.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>

#include "qota/atomic_file.hpp"
#include "qota/error.hpp"
#include "qota/geoid.hpp"
#include "qota/memory_budget.hpp"
#include "qota/shadow_tiles.hpp"
#include "qota/sunlight.hpp"
#include "cancel.hpp"
#include "raster_output.hpp"
#include "shadow_parts.hpp"
#include "text_output.hpp"
#include "tile_metadata.hpp"
#include "qota/version.hpp"

namespace qota::tools {
namespace {

// What a run by tiles holds besides the tiles' windows: the process as it is when the run starts
// (its libraries, measured then), what PROJ's database and GDAL's drivers add once used (measured
// up to 8 MiB on the test rasters, with GDAL's cache of a small tile; kLater), GDAL's block cache
// (a thirty-second of the budget, 2 to 64 MiB: it holds the blocks read and the output's blocks
// until written) and the tile's values.
constexpr std::uint64_t kLater = 8ull << 20;
constexpr std::uint64_t kTileBytesPerPixel = 16;  // the values written and the tile's lights

std::uint64_t gdalCacheFor(std::uint64_t allowed) {
  return std::clamp<std::uint64_t>(allowed / 32, 2ull << 20, 64ull << 20);
}
// The whole raster's run loads more of GDAL and PROJ than a tile's (measured up to 11 MiB).
constexpr std::uint64_t kWholeLater = 12ull << 20;

// Measured rates on one core of this project's reference machine (bench/shadow_tiles.sh): the
// pass over the heights reads 60 M pixels a second or more, and shadows by tiles take about 0.4 us
// a pixel at mid suns (more at low ones). For estimates printed before long work, not promises.
constexpr double kPassPixelsPerSecond = 60e6;
constexpr double kShadowPixelsPerSecond = 2.5e6;

std::uint64_t memoryAllowed(const ShadowOptions& o) {
  if (o.maxMemory) return o.maxMemory;
  const std::uint64_t available = memory::availableBytes();
  return available ? available / 4 * 3 : 4ull << 30;
}

// Bytes a pixel of the band takes (GDAL's cache holds blocks of them).
std::uint64_t pixelBytes(const std::string& path, int band) {
  std::unique_ptr<GDALDataset> ds(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER));
  GDALRasterBand* b = ds ? ds->GetRasterBand(std::max(1, band)) : nullptr;
  return b ? static_cast<std::uint64_t>(GDALGetDataTypeSizeBytes(b->GetRasterDataType())) : 8;
}

// What the geoid grid the frame loads takes (qota/geoid.hpp: its nodes as floats), when the run
// is on the ellipsoid and the heights are over a geoid; 0 else (or when it cannot be told: the
// frame's own error comes later).
std::uint64_t geoidBytes(const ShadowOptions& o, const DemTerrain& dem) {
  // The geoid's nodes over the raster, as its frame reads them (qota::Geoid's window).
  if (o.flat || dem.crsWkt.empty()) return 0;
  try {
    const FrameBasis basis = frameBasis(dem, frameOptionsOf(o));
    return basis.geoid ? basis.geoid->bytes() : 0;
  } catch (const Error&) {
    return 0;  // (the run says what is wrong)
  }
}

std::string mib(std::uint64_t bytes) { return std::to_string((bytes + (1 << 20) - 1) >> 20) + " MiB"; }

std::string clock(double seconds) {
  const auto s = static_cast<long long>(std::llround(std::min(std::max(0.0, seconds), 3.6e9)));
  char text[32];
  std::snprintf(text, sizeof text, "%lld:%02lld:%02lld", s / 3600, s / 60 % 60, s % 60);
  return text;
}

// A progress line that moves within a second on any input: "what: 12.3 %, 0:00:04 elapsed, ETA
// 0:00:29", rewritten at most ten times a second; none when quiet.
Progress etaProgress(bool quiet, std::ostream& out, const std::string& what) {
  if (quiet) return [](double, const char*) { return !cancelRequested(); };
  const auto started = std::chrono::steady_clock::now();
  auto shown = started - std::chrono::seconds(1);
  return [&out, what, started, shown](double done, const char*) mutable {
    if (cancelRequested()) return false;
    const auto now = std::chrono::steady_clock::now();
    if (done < 1 && now - shown < std::chrono::milliseconds(100)) return true;
    shown = now;
    const double elapsed = std::chrono::duration<double>(now - started).count();
    out << '\r' << what << ": " << formatNumber(100 * done, 3) << " %, " << clock(elapsed) << " elapsed";
    if (done > 0 && done < 1) out << ", ETA " << clock(elapsed / done - elapsed);
    out << "   " << (done >= 1 ? "\n" : "") << std::flush;
    return true;
  };
}

// The tiles, from the state file when there is one, else from a pass over the heights (then
// written to the state file, when asked, at once: other jobs may use it while this one works).
ShadowTiles passOverHeights(const ShadowOptions& o, const DemOptions& demOptions, const FrameOptions& frameOptions,
                            std::uint64_t passBytes, std::ostream& out) {
  std::error_code ec;
  if (!o.tilesState.empty() && std::filesystem::exists(std::filesystem::symlink_status(o.tilesState, ec))) {
    const std::string text = readSmallFile(o.tilesState, ShadowTiles::kMostStateBytes);
    try {
      return ShadowTiles::restore(text, o.source, demOptions, frameOptions);
    } catch (const Error& e) {
      throw Error(o.tilesState + ": " + e.what());
    }
  }
  ShadowTiles tiles(o.source, demOptions, frameOptions, etaProgress(o.quiet, out, "reading the heights"), passBytes);
  if (!o.tilesState.empty()) {
    AtomicFile file(o.tilesState);
    file.stream() << tiles.state();
    file.commit();
  }
  return tiles;
}

}  // namespace

std::vector<Eigen::Vector3d> lightsForEstimate(const ShadowOptions& o) {
  // Only the light's altitude matters: -az/-alt and --sun-vector say it; an instant, hours or a
  // body's vector are placed on the raster's frame (its centre and body, without its heights).
  try {
    DemOptions demOptions;
    demOptions.band = o.band;
    demOptions.lonLatAsCartesian = true;
    const DemTerrain dem = describeDem(o.source, demOptions);
    const FrameBasis basis = frameBasis(dem, frameOptionsOf(o));
    const LocalFrame& f = basis.shared;
    // A light below every pixel's horizon by more than the horizon's dip shades the whole raster
    // without a mask (shadowMask's shortcut): a bound of that slack from the raster's extent (the
    // angle from its centre to its corners) and the dip from 9 km of relief, a degree more.
    double slack = 0;
    if (f.body.ellipsoid) {
      const auto& g = dem.geotransform;
      const double cornerX = std::fabs(g[1]) * dem.width / 2 + std::fabs(g[2]) * dem.height / 2;
      const double cornerY = std::fabs(g[4]) * dem.width / 2 + std::fabs(g[5]) * dem.height / 2;
      const double across =
          basis.geographic ? std::hypot(cornerX, cornerY) : std::hypot(cornerX, cornerY) / f.body.a * 180 / M_PI;
      slack = std::min(180.0, across) + std::acos(f.body.b / (f.body.b + 9000.0)) * 180 / M_PI + 1.0;
    }
    const auto masked = [&](const Eigen::Vector3d& light) {
      const double altitude = std::asin(std::clamp(light.normalized().z(), -1.0, 1.0)) * 180 / M_PI;
      return f.body.ellipsoid ? altitude > -slack : altitude > 0;
    };
    const Eigen::Vector3d none(0, 0, 1);  // (a light whose mask costs the least: none is made)
    if (o.hours) {
      std::vector<Eigen::Vector3d> lights;
      const LocalSpan span = hoursSpan(o);
      for (const SunlightStep& step :
           qota::sunlightSteps(span.start.julianDayUT, span.end.julianDayUT, (*o.hours)[2])) {
        const Eigen::Vector3d light = f.towardSun(sunOverFrame(f, step.middleJulianDay, o.source));
        if (masked(light)) lights.push_back(light);
      }
      if (lights.empty()) lights.push_back(none);
      return lights;
    }
    std::ostringstream quiet;
    ShadowOptions q = o;
    q.quiet = true;
    const Eigen::Vector3d light = chooseLight(q, f, quiet).toward;
    return {masked(light) ? light : none};
  } catch (const std::exception&) {
    // (the run says what is wrong; the estimate takes the light's altitude alone, or the costliest)
    if (o.sunVector && o.sunVector->allFinite()) return {*o.sunVector};
    if (o.time.empty() && !o.hours && !o.sunVectorBody && !o.subsolar) {
      const double alt = o.altitude.value_or(45) * M_PI / 180;
      return {Eigen::Vector3d(0, std::cos(alt), std::sin(alt))};
    }
    return {};
  }
}

std::uint64_t wholeEstimate(const ShadowOptions& o, std::uint64_t resident) {
  DemOptions demOptions;
  demOptions.band = o.band;
  demOptions.lonLatAsCartesian = true;
  const DemTerrain d = describeDem(o.source, demOptions);
  const std::uint64_t pixels = static_cast<std::uint64_t>(d.width) * static_cast<std::uint64_t>(d.height);
  // The process, what its libraries add, the raster's and the output's blocks in GDAL's cache,
  // the terrain, its frame and the mask (or the hours and their step's mask).
  return resident + kWholeLater + geoidBytes(o, d) + pixels * (pixelBytes(o.source, o.band) + (o.hours ? 4 + 16 : 1)) +
         pixels * ShadowTiles::bytesPerWholePixel(lightsForEstimate(o));
}

FrameOptions frameOptionsOf(const RasterJobOptions& o) {
  FrameOptions f;
  f.flat = o.flat, f.pixelSize = o.pixelSize, f.zFactor = o.zFactor, f.scale = o.scale, f.heightRef = o.heightRef;
  return f;
}

void refuseBeyondMaxPixels(const ShadowOptions& o, const DemTerrain& described) {
  const double pixels = static_cast<double>(described.width) * static_cast<double>(described.height);
  if (pixels <= static_cast<double>(o.maxPixels)) return;
  throw Error(o.source + ": " + std::to_string(described.width) + " x " + std::to_string(described.height) +
              " pixels (" + formatReadable(pixels, 0) + "), more than --max-pixels " + std::to_string(o.maxPixels) +
              " allows: at the measured rates, reading its heights takes about " +
              clock(pixels / kPassPixelsPerSecond) + " and its shadows about " +
              clock(pixels / kShadowPixelsPerSecond) + (o.hours ? " a step" : "") + "; give --max-pixels " +
              std::to_string(static_cast<std::uint64_t>(pixels)) + " to run it");
}

bool runsByTiles(const ShadowOptions& o) {
  if (o.tileSize > 0 || o.tile || !o.tilesState.empty()) return true;
  return wholeEstimate(o, memory::residentBytes()) > memoryAllowed(o);
}

int shadowByTiles(const ShadowOptions& o, const std::string& format, std::ostream& out, std::ostream& err) {
  try {
    if (!o.png.empty()) {
      throw Error(
          "--png is drawn from the whole raster in memory; not with tiles (leave out --tile-size, --tile "
          "and --max-memory, or draw the preview from the output)");
    }
    if (o.tile && o.tileSize <= 0) throw Error("--tile COL,ROW needs --tile-size N (the tile grid it counts in)");
    if (o.tileSize < 0 || (o.tileSize > 0 && o.tileSize % 16 != 0)) {
      throw Error("--tile-size " + std::to_string(o.tileSize) +
                  ": give a positive multiple of 16 (a GeoTIFF's blocks; 256, 512, 1024...)");
    }
    // The budget: the process as it is now, GDAL's cache scaled to the budget, and the rest for
    // the tiles' windows.
    const std::uint64_t allowed = memoryAllowed(o);
    DemOptions demOptions;
    demOptions.band = o.band;
    demOptions.lonLatAsCartesian = true;
    const DemTerrain described = describeDem(o.source, demOptions);
    const double pixels = static_cast<double>(described.width) * static_cast<double>(described.height);
    // GDAL's cache need hold no more than the raster's blocks and the output's.
    const std::uint64_t cache = std::min<std::uint64_t>(
        gdalCacheFor(allowed),
        std::max<double>(1 << 20, pixels * static_cast<double>(pixelBytes(o.source, o.band) + (o.hours ? 4 : 1))));
    const std::uint64_t fixed = memory::residentBytes() + kLater + cache + geoidBytes(o, described);
    if (allowed <= fixed + (1ull << 20)) {
      throw Error("--max-memory " + mib(allowed) + ": the process itself takes " + mib(fixed - cache) +
                  " and GDAL's cache " + mib(cache) + " before any tile; allow at least " + mib(fixed + (8ull << 20)));
    }
    const std::uint64_t windowBytes = allowed - fixed;
    GDALSetCacheMax64(static_cast<GIntBig>(cache));
    const auto started = std::chrono::steady_clock::now();
    const auto seconds = [&] {
      return std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    };

    const FrameOptions frameOptions = frameOptionsOf(o);
    // Work sized before it starts: the pass over the heights reads every pixel, and the shadows
    // take each about a microsecond; a raster beyond --max-pixels is refused with the estimate.
    const double passSeconds = o.tilesState.empty() ? pixels / kPassPixelsPerSecond : 0;
    const double shadowSeconds = (o.tile ? std::min(pixels, double(o.tileSize) * o.tileSize) : pixels) /
                                 kShadowPixelsPerSecond * (o.hours ? 10.0 : 1.0);
    refuseBeyondMaxPixels(o, described);
    if (!o.quiet) {
      out << "estimate: " << formatReadable(pixels, 0) << " pixels; "
          << (passSeconds > 0 ? "reading the heights about " + clock(passSeconds) + ", " : std::string())
          << "the shadows about " << clock(shadowSeconds) << (o.hours ? " (hours: more at many steps)" : "") << '\n';
    }
    if (o.tile) {  // checked before the pass over the heights, which a large raster makes long
      const DemTerrain& d = described;
      const int across = (d.width + o.tileSize - 1) / o.tileSize, down = (d.height + o.tileSize - 1) / o.tileSize;
      const auto [c, r] = *o.tile;
      if (c < 0 || r < 0 || c >= across || r >= down) {
        throw Error("--tile " + std::to_string(c) + "," + std::to_string(r) + ": the raster has " +
                    std::to_string(across) + " x " + std::to_string(down) + " tiles of " + std::to_string(o.tileSize) +
                    " pixels (columns 0.." + std::to_string(across - 1) + ", rows 0.." + std::to_string(down - 1) +
                    ")");
      }
    }
    if (!o.quiet) out << "qota shadow: " << o.source << " -> " << o.output << " (" << format << ", by tiles)\n";
    // The pass over the heights holds a band of rows: half the windows' share at most.
    const std::uint64_t passBytes = std::clamp<std::uint64_t>(windowBytes / 2, 1ull << 20, ShadowTiles::kPassBytes);
    std::error_code ec;
    const bool restoring =
        !o.tilesState.empty() && std::filesystem::exists(std::filesystem::symlink_status(o.tilesState, ec));
    const ShadowTiles tiles = passOverHeights(o, demOptions, frameOptions, passBytes, out);
    const LocalFrame& frame = tiles.frame();
    const DemTerrain& dem = tiles.dem();
    if (!o.quiet) out << "frame: " << frame.description << '\n';

    // The lights: one, or every step of the hours that may be lit.
    std::vector<Eigen::Vector3d> lights;
    std::optional<LocalSpan> span;
    std::string lightText;  // for the tiles' fingerprint
    if (o.hours) {
      span = hoursSpan(o);
      lights = tiles.sunlightSteps(span->start.julianDayUT, span->end.julianDayUT, (*o.hours)[2], tiles.horizonSlack());
      lightText = "sunlight hours from " + span->start.utc + " to " + span->end.utc + " in steps of " +
                  formatNumber((*o.hours)[2]) + " h";
      if (!o.quiet) {
        out << "sunlight: from " << span->start.local << " (" << span->start.utc << ") to " << span->end.local << " ("
            << span->end.utc << "), steps of " << formatNumber((*o.hours)[2]) << " h, " << lights.size()
            << " with the Sun up\n";
      }
    } else {
      const LightChoice light = chooseLight(o, frame, out);
      if (!o.quiet) out << "light: " << light.description << '\n';
      lightText = light.description + "; toward " + formatNumber(light.toward.x()) + "," +
                  formatNumber(light.toward.y()) + "," + formatNumber(light.toward.z()) + " in the frame";
      if (light.toward.z() <= 0) {
        err << "qota shadow: the light is at or below the horizon at the centre"
            << (frame.body.ellipsoid ? "" : ": every pixel is in shadow") << '\n';
      }
      lights = {light.toward};
    }

    // The tile grid: the largest tiles (a multiple of 256 pixels a side, or of 16 below that)
    // whose windows, planned from the heights' block ranges, fit the budget.
    const std::uint64_t perPixel = ShadowTiles::bytesPerWindowPixel(lights) + kTileBytesPerPixel;
    const auto gridOf = [&](int s) {
      std::vector<PixelWindow> all;
      for (int r = 0; r < dem.height; r += s) {
        for (int c = 0; c < dem.width; c += s)
          all.push_back({c, r, std::min(s, dem.width - c), std::min(s, dem.height - r)});
      }
      return all;
    };
    const auto fits = [&](int s) { return tiles.largestWindowPixels(gridOf(s), lights) * perPixel <= windowBytes; };
    int side = o.tileSize;
    if (side <= 0) {
      for (const int multiple : {256, 16}) {
        int lo = 0, hi = (std::max(dem.width, dem.height) + multiple - 1) / multiple;  // lo fits (0: none), hi + 1 not
        if (fits(hi * multiple)) lo = hi;
        while (hi - lo > 1) {
          const int mid = (lo + hi) / 2;
          (fits(mid * multiple) ? lo : hi) = mid;
        }
        side = lo * multiple;
        if (side > 0) break;
      }
    }
    if (side == 0) {
      const std::uint64_t need = tiles.largestWindowPixels(gridOf(16), lights) * perPixel;
      throw Error("--max-memory " + mib(allowed) + ": even tiles of 16 pixels need windows of up to " + mib(need) +
                  " to hold every triangle that can shade them (a low sun's reach), so the run takes about " +
                  mib(fixed + need) + "; allow that much, or use a higher sun");
    }
    const int across = (dem.width + side - 1) / side, down = (dem.height + side - 1) / side;
    std::vector<std::array<int, 2>> todo;
    if (o.tile) {
      todo.push_back(*o.tile);  // (on the grid: checked above)
    } else {
      for (int r = 0; r < down; ++r) {
        for (int c = 0; c < across; ++c) todo.push_back({c, r});
      }
    }
    const auto tileOf = [&](const std::array<int, 2>& t) {
      const int col = t[0] * side, row = t[1] * side;
      return PixelWindow{col, row, std::min(side, dem.width - col), std::min(side, dem.height - row)};
    };
    // The memory estimate, from the windows the tiles to do will read.
    std::vector<PixelWindow> planned;
    planned.reserve(todo.size());
    for (const auto& t : todo) planned.push_back(tileOf(t));
    const std::uint64_t largest = tiles.largestWindowPixels(planned, lights);
    const std::uint64_t passRows = std::clamp<std::uint64_t>(passBytes / ShadowTiles::kPassBytesPerPixel / dem.width, 1,
                                                             static_cast<std::uint64_t>(dem.height));
    const std::uint64_t passHeld = restoring ? 0 : passRows * dem.width * ShadowTiles::kPassBytesPerPixel;
    const std::uint64_t estimate = fixed + std::max(passHeld, largest * perPixel);
    if (!o.quiet) {
      out << "tiles: " << todo.size() << " of " << side << " x " << side << " pixels (" << across << " x " << down
          << " over the raster); memory estimated " << mib(estimate) << " of " << mib(allowed)
          << " allowed (the process " << mib(fixed - cache) << ", GDAL's cache " << mib(cache) << ", windows of up to "
          << largest << " pixels)\n";
    }

    // The output: the whole raster, or the one tile's pixels, on the DEM's grid.
    StreamedRaster::Grid grid;
    const PixelWindow extent = o.tile ? tileOf(*o.tile) : PixelWindow{0, 0, dem.width, dem.height};
    grid.width = extent.width, grid.height = extent.height;
    grid.geotransform = dem.geotransform;
    grid.geotransform[0] += extent.col * dem.geotransform[1] + extent.row * dem.geotransform[2];
    grid.geotransform[3] += extent.col * dem.geotransform[4] + extent.row * dem.geotransform[5];
    grid.crsWkt = dem.crsWkt;
    grid.blockSize = StreamedRaster::blockFor(side);
    grid.nodata = o.hours ? -1.0 : double(o.nodataValue);
    grid.bandDescription = o.hours ? "hours of direct sunlight" : "shadow mask";
    grid.bandUnit = o.hours ? "h" : "";
    // The run's grid and everything the pixels depend on (tile_metadata.hpp), sealed when written.
    MetadataItems fingerprint{
        {"QOTA_VERSION", QOTA_VERSION_STRING},
        {"QOTA_SOURCE", std::filesystem::path(o.source).filename().string()},
        {"QOTA_HEIGHTS", "band " + std::to_string(dem.band) + ", hash " + hexOf(tiles.heightBlocks().whole()) +
                             " (blocks of " + std::to_string(tiles.heightBlocks().side()) + " pixels)"},
        {"QOTA_RASTER_SIZE", std::to_string(dem.width) + "," + std::to_string(dem.height)},
        {"QOTA_TILE_SIZE", std::to_string(side)},
        {"QOTA_TILES", std::to_string(across) + "," + std::to_string(down)},
        {"QOTA_FRAME",
         std::string("flat ") + (o.flat ? "yes" : "no") + ", pixel size " + formatNumber(o.pixelSize) + ", z factor " +
             formatNumber(o.zFactor) + ", scale " + formatNumber(o.scale) +
             (tiles.basis().geoid ? ", heights over the " + tiles.basis().heightRef.describe() : std::string())},
        {"QOTA_LIGHT", lightText},
        {"QOTA_VALUES", o.hours ? std::string("hours of direct sunlight, nodata -1")
                                : "lit " + std::to_string(o.litValue) + ", shadow " + std::to_string(o.shadowValue) +
                                      ", nodata " + std::to_string(o.nodataValue)}};
    if (o.tile) fingerprint.push_back({"QOTA_TILE", std::to_string((*o.tile)[0]) + "," + std::to_string((*o.tile)[1])});
    // What else the run records of its making (the version and frame, light and values are in the
    // fingerprint already): the tool, band, instant and zone, hours, command line.
    for (auto& item : withProvenance(shadowProvenance(o, dem.band, "", ""))) {
      const bool known =
          std::any_of(fingerprint.begin(), fingerprint.end(), [&item](const auto& f) { return f.first == item.first; });
      if (!known) fingerprint.push_back(std::move(item));
    }
    OutputStage stage;
    StreamedRaster output({o.output, format, o.creationOptions, !o.hours, o.hours ? -1.0 : double(o.nodataValue), true},
                          grid, stage);

    std::uint64_t lit = 0, valid = 0;
    std::vector<double> values;
    for (std::size_t k = 0; k < todo.size(); ++k) {
      throwIfCancelled();
      const PixelWindow tile = tileOf(todo[k]);
      values.resize(tile.pixelCount());
      if (o.hours) {
        const SunlightHours h = tiles.hours(tile, span->start.julianDayUT, span->end.julianDayUT, (*o.hours)[2],
                                            o.index, o.search, windowBytes);
        // Pixels without data: nodata (-1); the others their hours, 0 included.
        for (std::size_t i = 0; i < tile.pixelCount(); ++i) values[i] = h.valid[i] ? h.hours[i] : -1.0;
      } else {
        const std::vector<Light> mask = tiles.mask(tile, lights[0], o.index, 0, o.search, windowBytes);
        for (std::size_t i = 0; i < mask.size(); ++i) {
          values[i] = mask[i] == Light::Lit ? o.litValue : mask[i] == Light::Shadow ? o.shadowValue : o.nodataValue;
          lit += mask[i] == Light::Lit, valid += mask[i] != Light::NoData;
        }
      }
      output.write(tile.col - extent.col, tile.row - extent.row, tile.width, tile.height, values);
      if (!o.quiet) {
        const double elapsed = seconds(), done = static_cast<double>(k + 1) / todo.size();
        out << "\rtile " << k + 1 << "/" << todo.size() << " (" << formatNumber(100 * done, 3) << " %), "
            << clock(elapsed) << " elapsed, ETA " << clock(elapsed / done - elapsed) << "   " << std::flush;
      }
    }
    if (!o.quiet) out << '\n';
    if (o.tile) {  // the one tile's pixels
      PixelsHash pixels(!o.hours);
      pixels.add(values);
      fingerprint.push_back({"QOTA_PIXELS", pixels.hex()});
    }
    output.setMetadata(
        sealTile(fingerprint, {grid.width, grid.height, grid.geotransform, o.hours ? "Float32" : "Byte", grid.nodata}));
    output.finish();
    stage.commit();
    if (!o.quiet) {
      if (!o.hours) {
        out << "lit: " << formatNumber(valid ? 100.0 * lit / valid : 0.0, 2) << " % of " << valid << " pixels\n";
      }
      out << "written: " << o.output << '\n'
          << "memory: peak " << memory::peakBytes() / (1 << 20) << " MiB (estimated " << estimate / (1 << 20)
          << " MiB, allowed " << allowed / (1 << 20) << " MiB)\n"
          << "time: " << formatNumber(seconds(), 3) << " s\n";
    }
    return 0;
  } catch (...) {
    return reportFailure("shadow", err);
  }
}

}  // namespace qota::tools
