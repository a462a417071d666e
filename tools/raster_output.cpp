#include "raster_output.hpp"

#include <cpl_conv.h>
#include <cpl_string.h>
#include <gdal_priv.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <memory>

#include "gdal_errors.hpp"
#include "qota/error.hpp"

namespace qota::tools {
namespace {

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

}  // namespace

std::string driverForPath(const std::string& path) {
  ensureGdalRegistered();
  std::string ext = lower(std::filesystem::path(path).extension().string());
  if (!ext.empty() && ext[0] == '.') ext.erase(0, 1);
  if (ext.empty()) throw Error(path + ": no extension to guess the format from; give -of FORMAT");
  if (ext == "tif" || ext == "tiff") return "GTiff";  // not COG, which also claims .tif
  GDALDriverManager* dm = GetGDALDriverManager();
  for (int i = 0; i < dm->GetDriverCount(); ++i) {
    GDALDriver* d = dm->GetDriver(i);
    const char* exts = d->GetMetadataItem(GDAL_DMD_EXTENSIONS);
    const bool raster = d->GetMetadataItem(GDAL_DCAP_RASTER) != nullptr;
    const bool writes = d->GetMetadataItem(GDAL_DCAP_CREATE) || d->GetMetadataItem(GDAL_DCAP_CREATECOPY);
    if (!exts || !raster || !writes) continue;
    const CPLStringList list(CSLTokenizeString(exts));
    for (int k = 0; k < list.size(); ++k) {
      if (lower(list[k]) == ext) return d->GetDescription();
    }
  }
  throw Error(path + ": no GDAL driver writes '." + ext + "' files; give -of FORMAT");
}

void writeRaster(const RasterWrite& w, const DemTerrain& grid, const std::vector<double>& values, OutputStage& stage) {
  ensureGdalRegistered();
  const std::string format = w.format.empty() ? driverForPath(w.path) : w.format;
  GDALDriver* driver = GetGDALDriverManager()->GetDriverByName(format.c_str());
  if (!driver) throw Error("-of " + format + ": no such GDAL driver");
  if (!driver->GetMetadataItem(GDAL_DCAP_CREATE) && !driver->GetMetadataItem(GDAL_DCAP_CREATECOPY)) {
    throw Error("-of " + format + ": GDAL cannot write this format");
  }
  if (values.size() < static_cast<std::size_t>(grid.width) * grid.height) {
    throw Error(w.path + ": fewer values than cells");
  }
  CPLStringList co;
  for (const auto& o : w.creationOptions) {
    if (o.find('=') == std::string::npos) throw Error("-co " + o + ": expected NAME=VALUE");
    co.AddString(o.c_str());
  }
  GDALDriver* mem = GetGDALDriverManager()->GetDriverByName("MEM");
  const GDALDataType type = w.byteData ? GDT_Byte : GDT_Float32;
  std::unique_ptr<GDALDataset> ds(mem->Create("", grid.width, grid.height, 1, type, nullptr));
  if (!ds) throw Error(w.path + ": cannot allocate the output raster");
  double gt[6];
  std::copy(grid.geotransform.begin(), grid.geotransform.end(), gt);
  ds->SetGeoTransform(gt);
  if (!grid.crsWkt.empty()) ds->SetProjection(grid.crsWkt.c_str());
  GDALRasterBand* band = ds->GetRasterBand(1);
  band->SetNoDataValue(w.nodata);
  if (band->RasterIO(GF_Write, 0, 0, grid.width, grid.height, const_cast<double*>(values.data()),
                     grid.width, grid.height, GDT_Float64, 0, 0) != CE_None) {
    throw Error(w.path + ": cannot fill the output raster");
  }

  // Written into the stage (staged files move into place only when everything is written). Any
  // error GDAL reports while writing or closing (a full disk shows up at the close) fails it.
  const std::filesystem::path staged = stage.stage(w.path);
  detail::GdalErrorLog errors;
  std::unique_ptr<GDALDataset> copy(driver->CreateCopy(staged.c_str(), ds.get(), FALSE, co.List(),
                                                       w.quiet ? GDALDummyProgress : GDALTermProgress, nullptr));
  const bool created = copy != nullptr;
  copy.reset();  // flush and close
  if (!created || errors.failed()) {
    throw Error(w.path + ": cannot write" + (errors.message().empty() ? std::string() : " (" + errors.message() + ")"));
  }
}

}  // namespace qota::tools
