// Small rasters and files for tests, written and read with GDAL directly (not through qota).
#pragma once

#include <gdal_priv.h>
#include <gdal_utils.h>
#include <ogr_spatialref.h>

#include <array>
#include <filesystem>
#include <memory>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "qota/dem.hpp"

namespace qota::test {

// A fresh path in the tests' scratch folder.
inline std::filesystem::path scratchPath(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() / "qota_tests";
  std::filesystem::create_directories(dir);
  return dir / name;
}

struct RasterSpec {
  int width = 0, height = 0;
  std::array<double, 6> geotransform{0, 1, 0, 0, 0, -1};
  std::string crs;                         // anything SetFromUserInput takes; "" for none
  std::vector<std::vector<double>> bands;  // row-major values, one vector per band
  std::optional<double> nodata;
  std::string unitType;  // band unit type ("ft", ...), "" for none
  GDALDataType type = GDT_Float64;
  std::string driver = "GTiff";
};

inline void writeRaster(const std::filesystem::path& path, const RasterSpec& s) {
  ensureGdalRegistered();
  GDALDriver* drv = GetGDALDriverManager()->GetDriverByName(s.driver.c_str());
  if (!drv) throw std::runtime_error("no GDAL driver " + s.driver);
  std::unique_ptr<GDALDataset> ds(
      drv->Create(path.c_str(), s.width, s.height, static_cast<int>(s.bands.size()), s.type, nullptr));
  if (!ds) throw std::runtime_error("cannot create " + path.string());
  double gt[6];
  std::copy(s.geotransform.begin(), s.geotransform.end(), gt);
  ds->SetGeoTransform(gt);
  if (!s.crs.empty()) {
    OGRSpatialReference srs;
    if (srs.SetFromUserInput(s.crs.c_str()) != OGRERR_NONE) throw std::runtime_error("bad CRS " + s.crs);
    ds->SetSpatialRef(&srs);
  }
  for (std::size_t b = 0; b < s.bands.size(); ++b) {
    GDALRasterBand* band = ds->GetRasterBand(static_cast<int>(b + 1));
    if (s.nodata) band->SetNoDataValue(*s.nodata);
    if (!s.unitType.empty()) band->SetUnitType(s.unitType.c_str());
    if (band->RasterIO(GF_Write, 0, 0, s.width, s.height, const_cast<double*>(s.bands[b].data()), s.width, s.height,
                       GDT_Float64, 0, 0) != CE_None) {
      throw std::runtime_error("cannot write " + path.string());
    }
  }
}

// The window of `width` x `height` pixels at (`col`, `row`) of `source`, written to `path` as a
// GeoTIFF (gdal_translate -srcwin): its georeferencing, CRS, nodata and unit kept.
inline void cropRaster(const std::string& source, const std::filesystem::path& path, int col, int row, int width,
                       int height) {
  ensureGdalRegistered();
  std::unique_ptr<GDALDataset> in(GDALDataset::Open(source.c_str(), GDAL_OF_RASTER));
  if (!in) throw std::runtime_error("cannot open " + source);
  const std::string args[] = {
      "-srcwin", std::to_string(col), std::to_string(row), std::to_string(width), std::to_string(height), "-of",
      "GTiff"};
  std::vector<char*> argv;
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  GDALTranslateOptions* options = GDALTranslateOptionsNew(argv.data(), nullptr);
  std::unique_ptr<GDALDataset> out(
      GDALDataset::FromHandle(GDALTranslate(path.c_str(), GDALDataset::ToHandle(in.get()), options, nullptr)));
  GDALTranslateOptionsFree(options);
  if (!out) throw std::runtime_error("cannot crop " + source + " to " + path.string());
}

// Band `band` of a raster as doubles, row-major, with its size.
struct RasterValues {
  int width = 0, height = 0;
  std::array<double, 6> geotransform{};
  std::vector<double> values;
  double at(int col, int row) const { return values[static_cast<std::size_t>(row) * width + col]; }
};
inline RasterValues readRaster(const std::string& path, int band = 1) {
  ensureGdalRegistered();
  std::unique_ptr<GDALDataset> ds(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER));
  if (!ds) throw std::runtime_error("cannot open " + path);
  RasterValues r;
  r.width = ds->GetRasterXSize();
  r.height = ds->GetRasterYSize();
  double gt[6];
  ds->GetGeoTransform(gt);
  std::copy(gt, gt + 6, r.geotransform.begin());
  r.values.resize(static_cast<std::size_t>(r.width) * r.height);
  if (ds->GetRasterBand(band)->RasterIO(GF_Read, 0, 0, r.width, r.height, r.values.data(), r.width, r.height,
                                        GDT_Float64, 0, 0) != CE_None) {
    throw std::runtime_error("cannot read " + path);
  }
  return r;
}

// Lines of a text.
inline std::vector<std::string> linesOf(const std::string& s) {
  std::vector<std::string> v;
  std::istringstream in(s);
  for (std::string l; std::getline(in, l);) v.push_back(l);
  return v;
}

}  // namespace qota::test
