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
#include "qota/memory_budget.hpp"
#include "qota/shadow_tiles.hpp"
#include "qota/sunlight.hpp"
#include "raster_output.hpp"
#include "shadow_parts.hpp"
#include "text_output.hpp"
#include "tile_metadata.hpp"
#include "qota/version.hpp"

namespace qota::tools {
namespace {

// What a run by tiles holds besides the tiles' windows: the process with its libraries
// (memory::kProcessBase), GDAL's block cache (set to kGdalCache below) and a margin for the
// output's compression buffers and the tile's values.
constexpr std::uint64_t kGdalCache = 64ull << 20;
constexpr std::uint64_t kFixedBytes = memory::kProcessBase + kGdalCache + (32ull << 20);

// What the whole raster in memory takes (measured 170 bytes a cell on the Rainier DEM's run,
// loadDem's mesh and the frame's together), with a margin.
constexpr std::uint64_t kWholeBytesPerCell = 220;

std::uint64_t memoryAllowed(const ShadowOptions& o) {
  if (o.maxMemory) return o.maxMemory;
  const std::uint64_t available = memory::availableBytes();
  return available ? available / 4 * 3 : 4ull << 30;
}

std::string clock(double seconds) {
  const auto s = static_cast<long long>(std::llround(std::max(0.0, seconds)));
  char text[32];
  std::snprintf(text, sizeof text, "%lld:%02lld:%02lld", s / 3600, s / 60 % 60, s % 60);
  return text;
}

// The tiles, from the state file when there is one, else from a pass over the heights (then
// written to the state file, when asked, at once: other jobs may use it while this one works).
ShadowTiles passOverHeights(const ShadowOptions& o, const DemOptions& demOptions, const FrameOptions& frameOptions) {
  std::error_code ec;
  if (!o.tilesState.empty() && std::filesystem::exists(std::filesystem::symlink_status(o.tilesState, ec))) {
    const std::string text = readSmallFile(o.tilesState, ShadowTiles::kMostStateBytes);
    try {
      return ShadowTiles::restore(text, o.source, demOptions, frameOptions);
    } catch (const Error& e) {
      throw Error(o.tilesState + ": " + e.what());
    }
  }
  ShadowTiles tiles(o.source, demOptions, frameOptions, termProgress(o.quiet, 0, 1));
  if (!o.tilesState.empty()) {
    AtomicFile file(o.tilesState);
    file.stream() << tiles.state();
    file.commit();
  }
  return tiles;
}

}  // namespace

bool runsByTiles(const ShadowOptions& o) {
  if (o.tileSize > 0 || o.tile || !o.tilesState.empty()) return true;
  DemOptions demOptions;
  demOptions.band = o.band;
  demOptions.lonLatAsCartesian = true;
  const DemTerrain d = describeDem(o.source, demOptions);
  const std::uint64_t cells = static_cast<std::uint64_t>(d.width) * static_cast<std::uint64_t>(d.height);
  return memory::kProcessBase + cells * kWholeBytesPerCell > memoryAllowed(o);
}

int shadowByTiles(const ShadowOptions& o, const std::string& format, std::ostream& out, std::ostream& err) {
  try {
    if (!o.png.empty()) {
      throw Error("--png is drawn from the whole raster in memory; not with tiles (leave out --tile-size, --tile "
                  "and --max-memory, or draw the preview from the output)");
    }
    if (o.tile && o.tileSize <= 0) throw Error("--tile COL,ROW needs --tile-size N (the tile grid it counts in)");
    if (o.tileSize < 0 || (o.tileSize > 0 && o.tileSize % 16 != 0)) {
      throw Error("--tile-size " + std::to_string(o.tileSize) +
                  ": give a positive multiple of 16 (a GeoTIFF's blocks; 256, 512, 1024...)");
    }
    const std::uint64_t allowed = memoryAllowed(o);
    if (allowed <= kFixedBytes) {
      throw Error("--max-memory " + memory::gib(allowed) + ": the process, GDAL's cache and the output take " +
                  memory::gib(kFixedBytes) + " before any tile; allow more");
    }
    const std::uint64_t windowBytes = allowed - kFixedBytes;
    GDALSetCacheMax64(static_cast<GIntBig>(kGdalCache));
    const auto started = std::chrono::steady_clock::now();
    const auto seconds = [&] {
      return std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    };

    DemOptions demOptions;
    demOptions.band = o.band;
    demOptions.lonLatAsCartesian = true;
    FrameOptions frameOptions;
    frameOptions.flat = o.flat;
    frameOptions.pixelSize = o.pixelSize;
    frameOptions.zFactor = o.zFactor;
    frameOptions.scale = o.scale;
    if (o.tile) {  // checked before the pass over the heights, which a large raster makes long
      const DemTerrain d = describeDem(o.source, demOptions);
      const int across = (d.width + o.tileSize - 1) / o.tileSize, down = (d.height + o.tileSize - 1) / o.tileSize;
      const auto [c, r] = *o.tile;
      if (c < 0 || r < 0 || c >= across || r >= down) {
        throw Error("--tile " + std::to_string(c) + "," + std::to_string(r) + ": the raster has " + std::to_string(across) +
                    " x " + std::to_string(down) + " tiles of " + std::to_string(o.tileSize) + " cells (columns 0.." +
                    std::to_string(across - 1) + ", rows 0.." + std::to_string(down - 1) + ")");
      }
    }
    if (!o.quiet) out << "qota shadow: " << o.source << " -> " << o.output << " (" << format << ", by tiles)\n";
    const ShadowTiles tiles = passOverHeights(o, demOptions, frameOptions);
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
            << (frame.body.ellipsoid ? "" : ": every cell is in shadow") << '\n';
      }
      lights = {light.toward};
    }

    // The tile grid.
    const int side = o.tileSize > 0 ? o.tileSize : tiles.tileSideFor(windowBytes, lights, 256);
    if (side == 0) {
      const std::array<int, 4> halo = tiles.haloFor(256, 256, lights);
      const std::uint64_t need =
          static_cast<std::uint64_t>(256 + halo[0] + halo[1]) * (256 + halo[2] + halo[3]) * ShadowTiles::bytesPerWindowCell();
      throw Error("--max-memory " + memory::gib(allowed) + ": a tile of 256 cells with the halo its shadows need (" +
                  std::to_string(halo[0] + halo[1]) + " x " + std::to_string(halo[2] + halo[3]) + " cells) takes " +
                  memory::gib(need + kFixedBytes) + "; allow that much, or use a higher sun");
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
      return CellWindow{col, row, std::min(side, dem.width - col), std::min(side, dem.height - row)};
    };
    if (!o.quiet) {
      out << "tiles: " << todo.size() << " of " << side << " x " << side << " cells (" << across << " x " << down
          << " over the raster), memory allowed " << memory::gib(allowed) << '\n';
    }

    // The output: the whole raster, or the one tile's cells, on the DEM's grid.
    StreamedRaster::Grid grid;
    const CellWindow extent = o.tile ? tileOf(*o.tile) : CellWindow{0, 0, dem.width, dem.height};
    grid.width = extent.width, grid.height = extent.height;
    grid.geotransform = dem.geotransform;
    grid.geotransform[0] += extent.col * dem.geotransform[1] + extent.row * dem.geotransform[2];
    grid.geotransform[3] += extent.col * dem.geotransform[4] + extent.row * dem.geotransform[5];
    grid.crsWkt = dem.crsWkt;
    grid.blockSize = StreamedRaster::blockFor(side);
    grid.nodata = o.hours ? -1.0 : double(o.nodataValue);
    // The run's grid and everything the cells depend on (tile_metadata.hpp), sealed when written.
    MetadataItems fingerprint{
        {"QOTA_VERSION", QOTA_VERSION_STRING},
        {"QOTA_SOURCE", std::filesystem::path(o.source).filename().string()},
        {"QOTA_HEIGHTS", "band " + std::to_string(dem.band) + ", hash " + hexOf(tiles.heightBlocks().whole()) +
                             " (blocks of " + std::to_string(tiles.heightBlocks().side()) + " cells)"},
        {"QOTA_RASTER_SIZE", std::to_string(dem.width) + "," + std::to_string(dem.height)},
        {"QOTA_TILE_SIZE", std::to_string(side)},
        {"QOTA_TILES", std::to_string(across) + "," + std::to_string(down)},
        {"QOTA_FRAME", std::string("flat ") + (o.flat ? "yes" : "no") + ", pixel size " + formatNumber(o.pixelSize) +
                           ", z factor " + formatNumber(o.zFactor) + ", scale " + formatNumber(o.scale)},
        {"QOTA_LIGHT", lightText},
        {"QOTA_VALUES", o.hours ? std::string("hours of direct sunlight, nodata -1")
                                : "lit " + std::to_string(o.litValue) + ", shadow " + std::to_string(o.shadowValue) +
                                      ", nodata " + std::to_string(o.nodataValue)}};
    if (o.tile) fingerprint.push_back({"QOTA_TILE", std::to_string((*o.tile)[0]) + "," + std::to_string((*o.tile)[1])});
    OutputStage stage;
    StreamedRaster output({o.output, format, o.creationOptions, !o.hours, o.hours ? -1.0 : double(o.nodataValue), true},
                          grid, stage);

    std::uint64_t lit = 0, valid = 0;
    std::vector<double> values;
    for (std::size_t k = 0; k < todo.size(); ++k) {
      const CellWindow tile = tileOf(todo[k]);
      values.resize(tile.cellCount());
      if (o.hours) {
        const SunlightHours h = tiles.hours(tile, span->start.julianDayUT, span->end.julianDayUT, (*o.hours)[2],
                                            o.terrain, o.search, windowBytes);
        // Cells without data: nodata (-1); the others their hours, 0 included.
        for (std::size_t i = 0; i < tile.cellCount(); ++i) values[i] = h.valid[i] ? h.hours[i] : -1.0;
      } else {
        const std::vector<Light> mask = tiles.mask(tile, lights[0], o.terrain, 0, o.search, windowBytes);
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
    if (o.tile) {  // the one tile's cells
      CellsHash cells(!o.hours);
      cells.add(values);
      fingerprint.push_back({"QOTA_CELLS", cells.hex()});
    }
    output.setMetadata(sealTile(fingerprint, {grid.width, grid.height, grid.geotransform,
                                              o.hours ? "Float32" : "Byte", grid.nodata}));
    output.finish();
    stage.commit();
    if (!o.quiet) {
      if (!o.hours) {
        out << "lit: " << formatNumber(valid ? 100.0 * lit / valid : 0.0, 2) << " % of " << valid << " cells\n";
      }
      out << "written: " << o.output << '\n'
          << "memory: peak " << memory::peakBytes() / (1 << 20) << " MiB (allowed " << allowed / (1 << 20) << " MiB)\n"
          << "time: " << formatNumber(seconds(), 3) << " s\n";
    }
    return 0;
  } catch (...) {
    return reportFailure("shadow", err);
  }
}

}  // namespace qota::tools
