// What a raster written by tiles says of itself, so that `qota assemble` joins only tiles of one
// run and refuses the rest by name: the run's tile grid and a fingerprint of everything the pixels
// depend on, as QOTA_* metadata items of the dataset, sealed by a checksum over them and the
// tile's own grid (size, geotransform, data type, nodata). Internal to the tool.
//
//   QOTA_RASTER_SIZE  W,H of the whole raster      QOTA_TILE_SIZE  pixels a side of a tile
//   QOTA_TILES        columns,rows of tiles         QOTA_TILE       col,row of this tile (--tile)
//   QOTA_SOURCE       the source's file name        QOTA_HEIGHTS    band, hash of its heights
//   QOTA_FRAME        --flat, --pixel-size, -z, -s  QOTA_LIGHT      the light, or the hours' span
//   QOTA_VALUES       the values written            QOTA_VERSION    qota's version
//   QOTA_PIXELS       hash of this tile's pixels as stored (--tile; QOTA_CELLS in qota 0.2)
//   QOTA_CHECKSUM     of all the above and the grid
#pragma once

#include <array>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "qota/height_blocks.hpp"

class GDALDataset;

namespace qota::tools {

using MetadataItems = std::vector<std::pair<std::string, std::string>>;

// The fields every tile of one run must share (all but QOTA_TILE, QOTA_PIXELS and QOTA_CHECKSUM),
// in the order they are compared.
const std::vector<std::string>& runFields();

// The tile's grid as the checksum covers it.
struct TileGrid {
  int width = 0, height = 0;
  std::array<double, 6> geotransform{};
  std::string dataType;  // GDAL's name ("Byte", "Float32")
  std::optional<double> nodata;
};

// A dataset's QOTA_* items (checksum included) and its grid, as sealTile and sealHolds take them.
// Throws qota::Error for an item longer than any qota writes (damage).
MetadataItems qotaItemsOf(GDALDataset& dataset);
TileGrid tileGridOf(GDALDataset& dataset);

// `items` with QOTA_CHECKSUM (of items and grid) added last.
MetadataItems sealTile(MetadataItems items, const TileGrid& grid);
// Whether `items` (a dataset's QOTA_* items, QOTA_CHECKSUM among them) are what sealTile made for
// this grid.
bool sealHolds(const MetadataItems& items, const TileGrid& grid);
// The hash of a tile's pixels as stored (QOTA_PIXELS): Byte or Float32 values, row-major, given
// whole or a band of rows at a time.
class PixelsHash {
 public:
  explicit PixelsHash(bool byteData) : byteData_(byteData) {}
  void add(const std::vector<double>& values);
  std::string hex() const { return hash_.hex(); }

 private:
  bool byteData_;
  StreamingHash hash_;
};

}  // namespace qota::tools
