// qota assemble: tiles on one grid joined into one raster (see qota_tools.hpp).
#include <gdal_priv.h>
#include <gdal_utils.h>
#include <ogr_spatialref.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <map>
#include <set>

#include "cancel.hpp"
#include "gdal_errors.hpp"
#include "qota_tools.hpp"
#include "qota/error.hpp"
#include "raster_output.hpp"
#include "text_output.hpp"
#include "tile_metadata.hpp"

namespace qota::tools {
namespace {

struct Tile {
  std::string path;
  int width = 0, height = 0;
  std::array<double, 6> gt{};
  std::string crs;
  GDALDataType type = GDT_Unknown;
  std::optional<double> nodata;
  std::map<std::string, std::string> qota;  // its QOTA_* metadata, sealed (tile_metadata.hpp)
  long long col = 0, row = 0;               // its place on the first tile's grid
  std::string description, unit;            // its band's
};

Tile describe(const std::string& path) {
  // A FIFO or a device would be waited on, or read without end: only files (and GDAL's own
  // virtual paths).
  if (path.rfind("/vsi", 0) != 0) {
    std::error_code ec;
    const auto status = std::filesystem::status(path, ec);
    if (!std::filesystem::exists(status)) throw Error(path + ": no such file");
    if (!std::filesystem::is_regular_file(status)) {
      throw Error(path + ": not a regular file (a FIFO, a device or a folder); give the tiles' files");
    }
  }
  detail::GdalErrorLog errors;
  std::unique_ptr<GDALDataset> ds(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER));
  if (!ds) throw Error(path + ": cannot open as a raster (" + errors.reason() + "): damaged, or not a tile");
  if (ds->GetRasterCount() != 1) {
    throw Error(path + ": " + std::to_string(ds->GetRasterCount()) + " bands; tiles have one");
  }
  Tile t;
  t.path = path;
  t.width = ds->GetRasterXSize(), t.height = ds->GetRasterYSize();
  if (ds->GetGeoTransform(t.gt.data()) != CE_None) throw Error(path + ": no geotransform: its place is unknown");
  if (const OGRSpatialReference* srs = ds->GetSpatialRef()) {
    char* wkt = nullptr;
    srs->exportToWkt(&wkt);
    t.crs = wkt ? wkt : "";
    CPLFree(wkt);
  }
  GDALRasterBand* band = ds->GetRasterBand(1);
  t.type = band->GetRasterDataType();
  t.description = band->GetDescription() ? band->GetDescription() : "";
  t.unit = band->GetUnitType() ? band->GetUnitType() : "";
  int has = 0;
  const double nodata = band->GetNoDataValue(&has);
  if (has) t.nodata = nodata;
  MetadataItems items;
  try {
    items = qotaItemsOf(*ds);
  } catch (const Error& e) {
    throw Error(path + ": " + e.what());
  }
  if (!items.empty() && !sealHolds(items, tileGridOf(*ds))) {
    throw Error(path +
                ": damaged or edited: its qota metadata, size, geotransform, data type or nodata value are "
                "not those it was written with (QOTA_CHECKSUM); compute the tile again");
  }
  for (auto& [name, value] : items) t.qota[name] = value;
  return t;
}

bool sameCrs(const std::string& a, const std::string& b) {
  if (a.empty() || b.empty()) return a.empty() && b.empty();
  OGRSpatialReference x, y;
  return x.importFromWkt(a.c_str()) == OGRERR_NONE && y.importFromWkt(b.c_str()) == OGRERR_NONE && x.IsSame(&y);
}

// Places every tile on the first one's grid, or says why it is not on it.
void place(std::vector<Tile>& tiles) {
  const Tile& first = tiles.front();
  const auto& g = first.gt;
  const double det = g[1] * g[5] - g[2] * g[4];
  if (det == 0) throw Error(first.path + ": a geotransform without area");
  for (Tile& t : tiles) {
    if (!sameCrs(t.crs, first.crs)) throw Error(t.path + ": its CRS is not " + first.path + "'s");
    for (int k : {1, 2, 4, 5}) {
      if (std::fabs(t.gt[k] - g[k]) > 1e-9 * std::max(std::fabs(g[1]), std::fabs(g[5]))) {
        throw Error(t.path + ": its pixel size or rotation differs from " + first.path + "'s");
      }
    }
    if (t.type != first.type) throw Error(t.path + ": its data type differs from " + first.path + "'s");
    if (t.nodata != first.nodata) throw Error(t.path + ": its nodata value differs from " + first.path + "'s");
    // The origin's offset in the first tile's pixels: whole numbers on one grid.
    const double dx = t.gt[0] - g[0], dy = t.gt[3] - g[3];
    const double c = (g[5] * dx - g[2] * dy) / det, r = (-g[4] * dx + g[1] * dy) / det;
    if (!(std::fabs(c) < 4e18 && std::fabs(r) < 4e18))
      throw Error(t.path + ": too far from " + first.path + " to share its grid");
    t.col = std::llround(c), t.row = std::llround(r);
    if (std::fabs(c - t.col) > 1e-6 || std::fabs(r - t.row) > 1e-6) {
      throw Error(t.path + ": not on " + first.path + "'s grid (it is " + formatNumber(c) + ", " + formatNumber(r) +
                  " pixels from it, not whole pixels)");
    }
  }
}

// What a field of the fingerprint is, for messages.
std::string fieldName(const std::string& field) {
  static const std::map<std::string, std::string> names{
      {"QOTA_VERSION", "qota version"},   {"QOTA_SOURCE", "source file name"},
      {"QOTA_HEIGHTS", "source heights"}, {"QOTA_RASTER_SIZE", "raster size"},
      {"QOTA_TILE_SIZE", "tile size"},    {"QOTA_TILES", "tile grid"},
      {"QOTA_FRAME", "frame options"},    {"QOTA_LIGHT", "light"},
      {"QOTA_VALUES", "output values"}};
  const auto n = names.find(field);
  return (n == names.end() ? field : n->second) + " (" + field + ")";
}

// "A,B" as two whole numbers in [lo, hi], or nullopt.
std::optional<std::array<long long, 2>> pairOf(const std::string& text, long long lo, long long hi) {
  std::array<long long, 2> v{};
  const char* p = text.data();
  const char* end = p + text.size();
  for (int k = 0; k < 2; ++k) {
    const auto [next, ec] = std::from_chars(p, end, v[k]);
    if (ec != std::errc() || v[k] < lo || v[k] > hi) return std::nullopt;
    p = next;
    if (k == 0) {
      if (p == end || *p != ',') return std::nullopt;
      ++p;
    }
  }
  if (p != end) return std::nullopt;
  return v;
}

// qota's tiles: every one of the first tile's run (each field of the fingerprint the same), on
// the grid the metadata declares, where its QOTA_TILE puts it, once, and none missing. Time in
// proportion to the tiles given, whatever grid their metadata declares.
void checkRun(const std::vector<Tile>& tiles) {
  const Tile& first = tiles.front();
  for (const Tile& t : tiles) {
    for (const std::string& key : runFields()) {
      const auto a = t.qota.find(key), b = first.qota.find(key);
      if (a == t.qota.end() || b == first.qota.end()) {
        if (a == t.qota.end() && b == first.qota.end()) continue;
        throw Error(t.path + ": from another run than " + first.path + " (one of them has no " + fieldName(key) + ")");
      }
      if (a->second != b->second) {
        throw Error(t.path + ": from another run than " + first.path + ": its " + fieldName(key) + " is '" + a->second +
                    "', " + first.path + "'s '" + b->second + "'");
      }
    }
  }
  const auto need = [&](const char* key) -> const std::string& {
    const auto v = first.qota.find(key);
    if (v == first.qota.end()) throw Error(first.path + ": its qota metadata has no " + key);
    return v->second;
  };
  constexpr long long kInt = 2147483647;
  const auto size = pairOf(need("QOTA_RASTER_SIZE"), 1, kInt), grid = pairOf(need("QOTA_TILES"), 1, kInt);
  const auto side = pairOf(need("QOTA_TILE_SIZE") + ",1", 1, kInt);
  if (!size || !grid || !side) throw Error(first.path + ": its qota metadata does not give a tile grid (damaged)");
  const long long w = (*size)[0], h = (*size)[1], s = (*side)[0], across = (*grid)[0], down = (*grid)[1];
  if (across != (w + s - 1) / s || down != (h + s - 1) / s) {
    throw Error(first.path + ": its QOTA_TILES (" + need("QOTA_TILES") +
                ") is not the grid of its QOTA_RASTER_SIZE and "
                "QOTA_TILE_SIZE (damaged)");
  }
  std::set<long long> present;  // row-major tile numbers
  const auto firstAt = pairOf(first.qota.count("QOTA_TILE") ? first.qota.at("QOTA_TILE") : "", 0, kInt);
  for (const Tile& t : tiles) {
    const auto it = t.qota.find("QOTA_TILE");
    const auto at = it == t.qota.end() ? std::nullopt : pairOf(it->second, 0, kInt);
    if (!at || !firstAt || (*at)[0] >= across || (*at)[1] >= down) {
      throw Error(t.path + ": its QOTA_TILE is not a tile of the run's " + std::to_string(across) + " x " +
                  std::to_string(down) + " grid");
    }
    const long long c = (*at)[0], r = (*at)[1];
    if (t.width != std::min(s, w - c * s) || t.height != std::min(s, h - r * s) ||
        t.col - first.col != (c - (*firstAt)[0]) * s || t.row - first.row != (r - (*firstAt)[1]) * s) {
      throw Error(t.path + ": not where its QOTA_TILE (" + it->second + ") puts it on the run's grid");
    }
    if (!present.insert(r * across + c).second) throw Error(t.path + ": tile " + it->second + " is given twice");
  }
  const long long total = across * down;
  const long long missingCount = total - static_cast<long long>(present.size());
  if (missingCount > 0) {
    std::string missing;
    int named = 0;
    for (long long k = 0; k < total && named < 10; ++k) {  // at most the tiles given + 10 steps
      if (present.count(k)) continue;
      missing += (missing.empty() ? "" : " ") + std::to_string(k % across) + "," + std::to_string(k / across);
      ++named;
    }
    throw Error(std::to_string(missingCount) + " of the run's " + std::to_string(total) +
                " tiles are missing (--tile " + missing + (missingCount > 10 ? " ..." : "") +
                "); compute them, or nothing is assembled");
  }
}

// Every tile there, none twice, none overlapping: by qota's tile metadata when every tile has it
// (checkRun), else by area.
void checkComplete(const std::vector<Tile>& tiles, long long width, long long height) {
  const bool fromQota = std::all_of(tiles.begin(), tiles.end(), [](const Tile& t) { return !t.qota.empty(); });
  if (fromQota) return checkRun(tiles);
  if (std::any_of(tiles.begin(), tiles.end(), [](const Tile& t) { return !t.qota.empty(); })) {
    const auto mine = std::find_if(tiles.begin(), tiles.end(), [](const Tile& t) { return !t.qota.empty(); });
    const auto other = std::find_if(tiles.begin(), tiles.end(), [](const Tile& t) { return t.qota.empty(); });
    throw Error(other->path + ": not a tile of qota's run (no qota metadata), unlike " + mine->path);
  }
  long long area = 0;
  for (std::size_t i = 0; i < tiles.size(); ++i) {
    area += static_cast<long long>(tiles[i].width) * tiles[i].height;
    for (std::size_t j = 0; j < i; ++j) {
      const Tile &a = tiles[i], &b = tiles[j];
      if (a.col < b.col + b.width && b.col < a.col + a.width && a.row < b.row + b.height && b.row < a.row + a.height) {
        throw Error(a.path + " overlaps " + b.path);
      }
    }
  }
  if (area != width * height) {
    throw Error("the tiles leave " + std::to_string(width * height - area) + " of the " +
                std::to_string(width * height) + " pixels of their extent uncovered; nothing is assembled");
  }
}

}  // namespace

int assemble(const AssembleOptions& o, std::ostream& out, std::ostream& err) {
  try {
    ensureGdalRegistered();
    if (o.tiles.empty()) throw Error("no tiles given");
    if (o.output.empty()) throw Error("an output file is needed: -o OUT");
    OutputStage::checkTarget(o.output);
    const std::string format = o.format.empty() ? driverForPath(o.output) : o.format;
    if (format != "GTiff" && format != "COG" && format != "VRT") {
      throw Error(o.output + ": tiles are assembled into a GeoTIFF, a COG or a VRT, not " + format);
    }
    if (format != "VRT") {
      for (const std::string& warning : checkCreationOptions(format, o.creationOptions, false, 255)) {
        err << "qota assemble: warning: GDAL: " << warning << '\n';
      }
    }
    std::vector<Tile> tiles;
    for (const std::string& path : o.tiles) {
      std::error_code ec;
      if (std::filesystem::equivalent(path, o.output, ec)) throw Error(path + " is also the output; give another name");
      tiles.push_back(describe(path));
    }
    place(tiles);
    long long c0 = tiles[0].col, r0 = tiles[0].row, c1 = c0, r1 = r0;
    for (const Tile& t : tiles) {
      c0 = std::min(c0, t.col), r0 = std::min(r0, t.row);
      c1 = std::max(c1, t.col + t.width), r1 = std::max(r1, t.row + t.height);
    }
    if (c1 - c0 > (1 << 30) || r1 - r0 > (1 << 30)) throw Error("the tiles span more than 2^30 pixels a side");
    checkComplete(tiles, c1 - c0, r1 - r0);
    for (Tile& t : tiles) t.col -= c0, t.row -= r0;
    const auto& g = tiles[0].gt;
    std::array<double, 6> gt = g;
    const long long fc = -tiles[0].col, fr = -tiles[0].row;  // the first tile's place from the new origin, negated
    gt[0] = g[0] + fc * g[1] + fr * g[2];
    gt[3] = g[3] + fc * g[4] + fr * g[5];

    OutputStage stage;
    if (format == "VRT" && (g[2] != 0 || g[4] != 0 || g[5] > 0)) {
      throw Error(o.output + ": a VRT mosaic holds north-up tiles only, and these are " +
                  (g[2] != 0 || g[4] != 0 ? "rotated" : "south-up") + " (their geotransform " + formatNumber(g[1]) +
                  "," + formatNumber(g[2]) + "," + formatNumber(g[4]) + "," + formatNumber(g[5]) +
                  "); assemble them into a GeoTIFF (-o OUT.tif)");
    }
    if (format == "VRT") {
      std::vector<std::string> absolute;
      std::vector<const char*> names;
      absolute.reserve(tiles.size()), names.reserve(tiles.size());
      for (const Tile& t : tiles) absolute.push_back(std::filesystem::absolute(t.path).string());
      for (const auto& a : absolute) names.push_back(a.c_str());
      const std::filesystem::path staged = stage.stage(o.output);
      detail::GdalErrorLog errors;
      int usageError = 0;
      GDALDatasetH vrt =
          GDALBuildVRT(staged.c_str(), static_cast<int>(names.size()), nullptr, names.data(), nullptr, &usageError);
      if (!vrt || usageError) throw Error(o.output + ": cannot build the VRT (" + errors.reason() + ")");
      GDALClose(vrt);
      if (errors.failed()) throw Error(o.output + ": cannot write the VRT (" + errors.message() + ")");
    } else {
      if (tiles[0].type != GDT_Byte && tiles[0].type != GDT_Float32) {
        throw Error(tiles[0].path + ": tiles of " + GDALGetDataTypeName(tiles[0].type) +
                    "; a GeoTIFF is assembled from Byte or Float32 tiles (qota shadow's); make a VRT instead");
      }
      StreamedRaster::Grid grid;
      grid.width = static_cast<int>(c1 - c0), grid.height = static_cast<int>(r1 - r0);
      grid.geotransform = gt;
      grid.crsWkt = tiles[0].crs;
      int block = 256;
      MetadataItems fingerprint;  // the run's, sealed again for the whole raster
      if (tiles[0].qota.count("QOTA_TILE_SIZE")) {
        block = StreamedRaster::blockFor(std::atoi(tiles[0].qota.at("QOTA_TILE_SIZE").c_str()));
        for (const auto& [key, value] : tiles[0].qota) {
          if (key == "QOTA_COMMAND") {
            fingerprint.push_back({"QOTA_TILE_COMMAND", value});  // (how the first tile was made)
          } else if (key != "QOTA_TILE" && key != "QOTA_PIXELS" && key != "QOTA_CELLS" && key != "QOTA_CHECKSUM") {
            fingerprint.push_back({key, value});
          }
        }
        if (!commandLine().empty()) fingerprint.push_back({"QOTA_COMMAND", commandLine()});
      }
      grid.bandDescription = tiles[0].description, grid.bandUnit = tiles[0].unit;
      grid.blockSize = block;
      grid.nodata = tiles[0].nodata;
      RasterWrite w{o.output, format, o.creationOptions, tiles[0].type == GDT_Byte, tiles[0].nodata.value_or(0), true};
      StreamedRaster output(w, grid, stage);
      std::vector<double> rows;
      for (std::size_t k = 0; k < tiles.size(); ++k) {
        throwIfCancelled();
        const Tile& t = tiles[k];
        detail::GdalErrorLog errors;
        std::unique_ptr<GDALDataset> ds(GDALDataset::Open(t.path.c_str(), GDAL_OF_RASTER));
        if (!ds) throw Error(t.path + ": cannot open as a raster (" + errors.reason() + ")");
        // (QOTA_CELLS: the same hash in tiles of qota 0.2)
        auto pixels = t.qota.find("QOTA_PIXELS");
        if (pixels == t.qota.end()) pixels = t.qota.find("QOTA_CELLS");
        PixelsHash read(t.type == GDT_Byte);
        for (int r = 0; r < t.height; r += block) {
          const int n = std::min(block, t.height - r);
          rows.resize(static_cast<std::size_t>(t.width) * n);
          if (ds->GetRasterBand(1)->RasterIO(GF_Read, 0, r, t.width, n, rows.data(), t.width, n, GDT_Float64, 0, 0) !=
                  CE_None ||
              errors.failed()) {
            throw Error(t.path + ": damaged: cannot read rows " + std::to_string(r) + ".." + std::to_string(r + n - 1) +
                        " (" + errors.reason() + ")");
          }
          if (pixels != t.qota.end()) read.add(rows);
          output.write(static_cast<int>(t.col), static_cast<int>(t.row) + r, t.width, n, rows);
        }
        if (pixels != t.qota.end() && read.hex() != pixels->second) {
          throw Error(t.path + ": damaged: its pixels are not those qota wrote (QOTA_PIXELS); compute the tile again");
        }
        if (!o.quiet) out << "\rtile " << k + 1 << "/" << tiles.size() << std::flush;
      }
      if (!o.quiet) out << '\n';
      if (!fingerprint.empty()) {
        output.setMetadata(sealTile(fingerprint, {grid.width, grid.height, grid.geotransform,
                                                  GDALGetDataTypeName(tiles[0].type), grid.nodata}));
      }
      output.finish();
    }
    stage.commit();
    if (!o.quiet) {
      out << "assembled: " << tiles.size() << " tiles, " << (c1 - c0) << " x " << (r1 - r0) << " pixels -> " << o.output
          << '\n';
    }
    return 0;
  } catch (...) {
    return reportFailure("assemble", err);
  }
}

std::uint64_t parseByteSize(const std::string& text) {
  std::size_t used = 0;
  double number = 0;
  try {
    number = std::stod(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  std::string unit = text.substr(used);
  std::transform(unit.begin(), unit.end(), unit.begin(), [](unsigned char c) { return std::toupper(c); });
  if (unit.size() > 1 && unit.back() == 'B') unit.pop_back();
  if (unit.size() > 1 && unit.back() == 'I') unit.pop_back();
  const std::map<std::string, double> scale{
      {"", 1}, {"B", 1}, {"K", 1024.0}, {"M", 1048576.0}, {"G", 1073741824.0}, {"T", 1099511627776.0}};
  const auto s = scale.find(unit);
  if (used == 0 || s == scale.end() || !(number > 0) || !(number * s->second < 1.8e19)) {
    throw Error("'" + text + "' is not a size; give bytes, or a number with K, M, G or T (64M, 2G, 1.5GiB)");
  }
  if (number * s->second < 1) throw Error("'" + text + "' is less than a byte; give a size such as 64M or 2G");
  return static_cast<std::uint64_t>(number * s->second);
}

}  // namespace qota::tools
