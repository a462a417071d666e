#include "raster_output.hpp"

#include <cpl_conv.h>
#include <cpl_string.h>
#include <gdal_priv.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <memory>

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

void writeRaster(const RasterWrite& w, const DemTerrain& grid, const std::vector<double>& values) {
  ensureGdalRegistered();
  const std::string format = w.format.empty() ? driverForPath(w.path) : w.format;
  GDALDriver* driver = GetGDALDriverManager()->GetDriverByName(format.c_str());
  if (!driver) throw Error("-of " + format + ": no such GDAL driver");
  if (!driver->GetMetadataItem(GDAL_DCAP_CREATE) && !driver->GetMetadataItem(GDAL_DCAP_CREATECOPY)) {
    throw Error("-of " + format + ": GDAL cannot write this format");
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

  // Temporary name in the same folder (rename must not cross file systems), same extension.
  const std::filesystem::path target(w.path);
  std::filesystem::path temp = target;
  temp.replace_filename("." + target.filename().string() + ".tmp" + std::to_string(::getpid()) +
                        target.extension().string());
  CPLStringList co;
  for (const auto& o : w.creationOptions) {
    if (o.find('=') == std::string::npos) throw Error("-co " + o + ": expected NAME=VALUE");
    co.AddString(o.c_str());
  }
  CPLPushErrorHandler(CPLQuietErrorHandler);
  CPLErrorReset();
  std::unique_ptr<GDALDataset> copy(driver->CreateCopy(temp.c_str(), ds.get(), FALSE, co.List(),
                                                       w.quiet ? GDALDummyProgress : GDALTermProgress,
                                                       nullptr));
  const std::string gdalError = CPLGetLastErrorMsg();
  CPLPopErrorHandler();
  const bool ok = copy != nullptr;
  copy.reset();  // flush and close before the rename
  std::error_code ec;
  const std::filesystem::path sidecar = temp.string() + ".aux.xml";
  if (!ok) {
    std::filesystem::remove(temp, ec);
    std::filesystem::remove(sidecar, ec);
    throw Error(w.path + ": cannot write" + (gdalError.empty() ? std::string() : " (" + gdalError + ")"));
  }
  std::filesystem::rename(temp, target, ec);
  if (ec) {
    std::filesystem::remove(temp, ec);
    throw Error(w.path + ": cannot rename into place (" + ec.message() + ")");
  }
  if (std::filesystem::exists(sidecar)) {
    std::filesystem::rename(sidecar, target.string() + ".aux.xml", ec);
  }
}

}  // namespace qota::tools
