// Writing rasters through GDAL, safely: the driver guessed from the file name unless given, the
// data assembled in memory, then copied into an OutputStage (qota/atomic_file.hpp), which the
// caller commits when all its outputs are written: a failed run never leaves a half-written
// raster, nor its sidecar files.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "qota/atomic_file.hpp"
#include "qota/dem.hpp"

namespace qota::tools {

// The GDAL driver that writes files with this name's extension ("GTiff" for .tif); throws
// qota::Error when none does.
std::string driverForPath(const std::string& path);

// One band on the DEM's grid and georeferencing. `type`: "Byte" or "Float32" (the values are
// converted). Throws qota::Error naming the file when it cannot be written.
struct RasterWrite {
  std::string path;
  std::string format;  // empty: driverForPath(path)
  std::vector<std::string> creationOptions;
  bool byteData = true;
  double nodata = 0;
  bool quiet = true;   // no progress on stdout
};
void writeRaster(const RasterWrite& w, const DemTerrain& grid, const std::vector<double>& values, OutputStage& stage);

}  // namespace qota::tools
