// The seal of a tile's metadata (see tile_metadata.hpp).
#include "tile_metadata.hpp"

#include <gdal_priv.h>

#include <algorithm>
#include <charconv>
#include <cstdint>

#include "qota/error.hpp"
#include "qota/height_blocks.hpp"

namespace qota::tools {
namespace {

std::string bits(double v) {
  char buffer[64];
  return std::string(buffer, std::to_chars(buffer, buffer + sizeof buffer, v, std::chars_format::hex).ptr);
}

// The text the checksum is of: the items but the checksum, sorted by name, then the grid.
std::string sealedText(MetadataItems items, const TileGrid& grid) {
  items.erase(std::remove_if(items.begin(), items.end(), [](const auto& i) { return i.first == "QOTA_CHECKSUM"; }),
              items.end());
  std::sort(items.begin(), items.end());
  std::string text;
  for (const auto& [name, value] : items) {
    text.append(name).append("=").append(std::to_string(value.size())).append(":").append(value).append("\n");
  }
  text += "size=" + std::to_string(grid.width) + "," + std::to_string(grid.height) + "\ngeotransform=";
  for (double g : grid.geotransform) text += bits(g) + ",";
  text += "\ntype=" + grid.dataType + "\nnodata=" + (grid.nodata ? bits(*grid.nodata) : std::string("none")) + "\n";
  return text;
}

}  // namespace

const std::vector<std::string>& runFields() {
  static const std::vector<std::string> fields{"QOTA_VERSION",     "QOTA_SOURCE",    "QOTA_HEIGHTS",
                                               "QOTA_RASTER_SIZE", "QOTA_TILE_SIZE", "QOTA_TILES",
                                               "QOTA_FRAME",       "QOTA_LIGHT",     "QOTA_VALUES"};
  return fields;
}

MetadataItems qotaItemsOf(GDALDataset& dataset) {
  constexpr std::size_t kLongestItem = 4096;  // a light's description is the longest qota writes
  MetadataItems items;
  for (char** item = dataset.GetMetadata(); item && *item; ++item) {
    const std::string text = *item;
    const auto eq = text.find('=');
    if (text.rfind("QOTA_", 0) != 0 || eq == std::string::npos) continue;
    if (text.size() > kLongestItem)
      throw Error("damaged: a QOTA_ metadata item of " + std::to_string(text.size()) + " bytes");
    items.push_back({text.substr(0, eq), text.substr(eq + 1)});
  }
  return items;
}

TileGrid tileGridOf(GDALDataset& dataset) {
  TileGrid grid;
  grid.width = dataset.GetRasterXSize(), grid.height = dataset.GetRasterYSize();
  if (dataset.GetGeoTransform(grid.geotransform.data()) != CE_None) grid.geotransform = {0, 1, 0, 0, 0, 1};
  GDALRasterBand* band = dataset.GetRasterCount() > 0 ? dataset.GetRasterBand(1) : nullptr;
  grid.dataType = band ? GDALGetDataTypeName(band->GetRasterDataType()) : "";
  int has = 0;
  const double nodata = band ? band->GetNoDataValue(&has) : 0;
  if (has) grid.nodata = nodata;
  return grid;
}

MetadataItems sealTile(MetadataItems items, const TileGrid& grid) {
  items.erase(std::remove_if(items.begin(), items.end(), [](const auto& i) { return i.first == "QOTA_CHECKSUM"; }),
              items.end());
  const std::string sum = checksumOf(sealedText(items, grid));
  items.push_back({"QOTA_CHECKSUM", sum});
  return items;
}

bool sealHolds(const MetadataItems& items, const TileGrid& grid) {
  const auto sum = std::find_if(items.begin(), items.end(), [](const auto& i) { return i.first == "QOTA_CHECKSUM"; });
  return sum != items.end() && sum->second == checksumOf(sealedText(items, grid));
}

void PixelsHash::add(const std::vector<double>& values) {
  if (byteData_) {
    std::vector<std::uint8_t> stored(values.size());
    for (std::size_t i = 0; i < values.size(); ++i) stored[i] = static_cast<std::uint8_t>(values[i]);
    hash_.add(stored.data(), stored.size());
    return;
  }
  std::vector<float> stored(values.size());
  for (std::size_t i = 0; i < values.size(); ++i) stored[i] = static_cast<float>(values[i]);
  hash_.add(stored.data(), stored.size() * sizeof(float));
}

}  // namespace qota::tools
