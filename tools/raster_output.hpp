// Writing rasters through GDAL, safely: the driver guessed from the file name unless given, the
// data assembled in memory, then copied into an OutputStage (qota/atomic_file.hpp), which the
// caller commits when all its outputs are written: a failed run never leaves a half-written
// raster, nor its sidecar files.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "qota/atomic_file.hpp"
#include "qota/dem.hpp"

namespace qota::tools {

// The GDAL driver that writes files with this name's extension ("GTiff" for .tif); throws
// qota::Error when none does.
std::string driverForPath(const std::string& path);
// The GDAL vector driver that writes files of the path's extension (.gpkg, .geojson, .shp, .fgb,
// .csv, ...). Throws qota::Error naming the path when none does.
std::string vectorDriverForPath(const std::string& path);

// Refuses creation options and formats that would change the values written (qota::Error naming
// the option): lossy compression (JPEG, WebP, JPEG XL or LERC with an error allowed, the JPEG
// and WebP formats), fewer bits than the values need (NBITS below what `mostValue` takes in a
// Byte band; 16-bit floats), signed bytes. Returns GDAL's own warnings on the rest (an option the
// driver does not know), for the tool to print. byteData: integer values (Byte, or counts; else Float32).
std::vector<std::string> checkCreationOptions(const std::string& format, const std::vector<std::string>& options,
                                              bool byteData, std::uint64_t mostValue);

// One band on the DEM's grid and georeferencing. `type`: "Byte" or "Float32" (the values are
// converted). Throws qota::Error naming the file when it cannot be written.
struct RasterWrite {
  std::string path;
  std::string format;  // empty: driverForPath(path)
  std::vector<std::string> creationOptions;
  bool byteData = true;
  double nodata = 0;
  bool quiet = true;                                               // no progress on stdout
  std::vector<std::pair<std::string, std::string>> metadata = {};  // NAME, VALUE items of the dataset
  std::string type = {};  // a GDAL data type name ("UInt16", "UInt32") instead of Byte / Float32
  // The band's description and unit ("hours of direct sunlight", "h"); empty: none.
  std::string bandDescription = {}, bandUnit = {};
};
// What every raster a tool writes records of its making, after the tool's own items: the qota
// version (QOTA_VERSION) and the command line (QOTA_COMMAND, when run as the qota command).
std::vector<std::pair<std::string, std::string>> withProvenance(std::vector<std::pair<std::string, std::string>> items);
void writeRaster(const RasterWrite& w, const DemTerrain& grid, const std::vector<double>& values, OutputStage& stage);

// One band written a window at a time, for rasters larger than memory: a tiled, DEFLATE-compressed
// GeoTIFF (BIGTIFF when it may pass 4 GB) in blocks of `blockSize` (a multiple of 16; windows
// aligned to it write each block once), staged like writeRaster. Format "COG": the GeoTIFF is
// copied into a cloud-optimized GeoTIFF (with overviews) when finished, then removed. Only these
// two formats. The caller's creation options come after (and so override) the defaults.
class StreamedRaster {
 public:
  struct Grid {
    int width = 0, height = 0;
    std::array<double, 6> geotransform{0, 1, 0, 0, 0, 1};
    std::string crsWkt;
    int blockSize = 256;
    std::optional<double> nodata;                               // the band's (RasterWrite's nodata is not used here)
    std::vector<std::pair<std::string, std::string>> metadata;  // NAME, VALUE items of the dataset
    std::string bandDescription = {}, bandUnit = {};
  };
  StreamedRaster(const RasterWrite& w, const Grid& grid, OutputStage& stage);
  // The largest block size (at most 256) that tiles of `side` pixels are made of, so that every
  // block is written once; 16 when none divides it.
  static int blockFor(int side);
  ~StreamedRaster();
  StreamedRaster(const StreamedRaster&) = delete;
  StreamedRaster& operator=(const StreamedRaster&) = delete;
  // Values of the pixels [col, col + width) x [row, row + height), row-major.
  void write(int col, int row, int width, int height, const std::vector<double>& values);
  // More NAME, VALUE items of the dataset (or new values for them), before finish().
  void setMetadata(const std::vector<std::pair<std::string, std::string>>& items);
  // Flushes and closes it (and makes the COG). Throws qota::Error naming the file on any error
  // (a full disk shows here); the stage then holds nothing to commit.
  void finish();

 private:
  struct Open;
  RasterWrite w_;
  std::unique_ptr<Open> open_;
};

}  // namespace qota::tools
