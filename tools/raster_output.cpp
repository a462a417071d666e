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
#include "qota/version.hpp"
#include "qota_tools.hpp"

namespace qota::tools {

std::vector<std::pair<std::string, std::string>> withProvenance(
    std::vector<std::pair<std::string, std::string>> items) {
  const auto has = [&items](const std::string& name) {
    return std::any_of(items.begin(), items.end(), [&name](const auto& i) { return i.first == name; });
  };
  if (!has("QOTA_VERSION")) items.emplace_back("QOTA_VERSION", QOTA_VERSION_STRING);
  if (!has("QOTA_COMMAND") && !commandLine().empty()) items.emplace_back("QOTA_COMMAND", commandLine());
  return items;
}
namespace {

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

}  // namespace

namespace {

// The first GDAL driver that writes files of `path`'s extension and has `capability` (rasters or
// vectors); `preferred` first where several claim it.
std::string writerForPath(const std::string& path, const char* capability,
                          const std::vector<std::pair<std::string, std::string>>& preferred) {
  ensureGdalRegistered();
  std::string ext = lower(std::filesystem::path(path).extension().string());
  if (!ext.empty() && ext[0] == '.') ext.erase(0, 1);
  if (ext.empty()) throw Error(path + ": no extension to guess the format from; give -of FORMAT");
  for (const auto& [e, driver] : preferred) {
    if (e == ext) return driver;
  }
  GDALDriverManager* dm = GetGDALDriverManager();
  for (int i = 0; i < dm->GetDriverCount(); ++i) {
    GDALDriver* d = dm->GetDriver(i);
    const char* exts = d->GetMetadataItem(GDAL_DMD_EXTENSIONS);
    const bool able = d->GetMetadataItem(capability) != nullptr;
    const bool writes = d->GetMetadataItem(GDAL_DCAP_CREATE) || d->GetMetadataItem(GDAL_DCAP_CREATECOPY);
    if (!exts || !able || !writes) continue;
    const CPLStringList list(CSLTokenizeString(exts));
    for (int k = 0; k < list.size(); ++k) {
      if (lower(list[k]) == ext) return d->GetDescription();
    }
  }
  throw Error(path + ": no GDAL driver writes '." + ext + "' files; give -of FORMAT");
}

}  // namespace

std::string driverForPath(const std::string& path) {
  return writerForPath(path, GDAL_DCAP_RASTER,
                       {{"tif", "GTiff"}, {"tiff", "GTiff"}});  // (not COG, which also claims .tif)
}

std::string vectorDriverForPath(const std::string& path) {
  return writerForPath(path, GDAL_DCAP_VECTOR, {{"json", "GeoJSON"}, {"geojson", "GeoJSON"}, {"csv", "CSV"}});
}

std::vector<std::string> checkCreationOptions(const std::string& format, const std::vector<std::string>& options,
                                              bool byteData, std::uint64_t mostValue) {
  ensureGdalRegistered();
  std::string f = format;
  std::transform(f.begin(), f.end(), f.begin(), [](unsigned char c) { return std::toupper(c); });
  CPLStringList co;
  for (const auto& o : options) {
    if (o.find('=') == std::string::npos) throw Error("-co " + o + ": expected NAME=VALUE");
    co.AddString(o.c_str());
  }
  const auto value = [&](const char* name) {
    std::string v = co.FetchNameValueDef(name, "");
    std::transform(v.begin(), v.end(), v.begin(), [](unsigned char c) { return std::toupper(c); });
    return v;
  };
  const auto refuse = [&](const std::string& what) {
    throw Error(what +
                ": the values written would not be the ones computed; give lossless options "
                "(COMPRESS=DEFLATE, LZW or ZSTD), or none");
  };
  if (f == "JPEG") refuse("-of JPEG (lossy)");
  if (f == "WEBP" && value("LOSSLESS") != "YES") refuse("-of WEBP without -co LOSSLESS=YES (lossy)");
  if (f == "JP2OPENJPEG" && value("REVERSIBLE") != "YES") refuse("-of JP2OpenJPEG without -co REVERSIBLE=YES (lossy)");
  const std::string compress = value("COMPRESS");
  if (compress == "JPEG") refuse("-co COMPRESS=JPEG (lossy)");
  if (compress == "WEBP" && value("WEBP_LOSSLESS") != "YES")
    refuse("-co COMPRESS=WEBP without WEBP_LOSSLESS=YES (lossy)");
  if (compress == "JXL" && value("JXL_LOSSLESS") == "NO") refuse("-co JXL_LOSSLESS=NO (lossy)");
  if (compress.rfind("LERC", 0) == 0 && std::atof(value("MAX_Z_ERROR").c_str()) != 0) {
    refuse("-co MAX_Z_ERROR=" + value("MAX_Z_ERROR") + " (lossy LERC)");
  }
  if (!value("NBITS").empty()) {
    const int bits = std::atoi(value("NBITS").c_str());
    int need = 1;
    while (need < 32 && (std::uint64_t{1} << need) <= mostValue) ++need;
    if (byteData && bits < need) {
      refuse("-co NBITS=" + value("NBITS") + " (the value " + std::to_string(mostValue) + " needs " +
             std::to_string(need) + " bits)");
    }
    if (!byteData && bits != 32) refuse("-co NBITS=" + value("NBITS") + " (hours are 32-bit floats)");
  }
  if (value("PIXELTYPE") == "SIGNEDBYTE") refuse("-co PIXELTYPE=SIGNEDBYTE (values over 127 read as negative)");
  // What GDAL itself says of the options (an unknown name, a value out of its list).
  std::vector<std::string> warnings;
  if (GDALDriver* driver = GetGDALDriverManager()->GetDriverByName(format == "COG" ? "COG" : format.c_str())) {
    detail::GdalErrorLog log;
    GDALValidateCreationOptions(driver, co.List());
    warnings = log.warnings();
    if (log.failed()) warnings.push_back(log.message());
  }
  return warnings;
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
    throw Error(w.path + ": fewer values than pixels");
  }
  CPLStringList co;
  for (const auto& o : w.creationOptions) {
    if (o.find('=') == std::string::npos) throw Error("-co " + o + ": expected NAME=VALUE");
    co.AddString(o.c_str());
  }
  GDALDriver* mem = GetGDALDriverManager()->GetDriverByName("MEM");
  const GDALDataType type = !w.type.empty() ? GDALGetDataTypeByName(w.type.c_str())
                            : w.byteData    ? GDT_Byte
                                            : GDT_Float32;
  if (type == GDT_Unknown) throw Error(w.path + ": no data type " + w.type);
  std::unique_ptr<GDALDataset> ds(mem->Create("", grid.width, grid.height, 1, type, nullptr));
  if (!ds) throw Error(w.path + ": cannot allocate the output raster");
  double gt[6];
  std::copy(grid.geotransform.begin(), grid.geotransform.end(), gt);
  ds->SetGeoTransform(gt);
  if (!grid.crsWkt.empty()) ds->SetProjection(grid.crsWkt.c_str());
  for (const auto& [name, value] : withProvenance(w.metadata)) ds->SetMetadataItem(name.c_str(), value.c_str());
  GDALRasterBand* band = ds->GetRasterBand(1);
  band->SetNoDataValue(w.nodata);
  if (!w.bandDescription.empty()) band->SetDescription(w.bandDescription.c_str());
  if (!w.bandUnit.empty()) band->SetUnitType(w.bandUnit.c_str());
  if (band->RasterIO(GF_Write, 0, 0, grid.width, grid.height, const_cast<double*>(values.data()), grid.width,
                     grid.height, GDT_Float64, 0, 0) != CE_None) {
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

namespace {

// The caller's creation options (NAME=VALUE) over the defaults in `co`.
void overrideWith(const std::vector<std::string>& options, CPLStringList& co) {
  for (const auto& option : options) {
    const auto eq = option.find('=');
    if (eq == std::string::npos) throw Error("-co " + option + ": expected NAME=VALUE");
    co.SetNameValue(option.substr(0, eq).c_str(), option.substr(eq + 1).c_str());
  }
}

}  // namespace

int StreamedRaster::blockFor(int side) {
  for (int b = 256; b >= 16; b /= 2) {
    if (side % b == 0) return b;
  }
  return 16;
}

struct StreamedRaster::Open {
  std::filesystem::path staged, tiff;  // tiff: the GeoTIFF written (staged itself unless COG)
  std::unique_ptr<GDALDataset> ds;
  GDALRasterBand* band = nullptr;
  GDALDataType type = GDT_Byte;
  bool cog = false;
  detail::GdalErrorLog errors;
};

StreamedRaster::StreamedRaster(const RasterWrite& w, const Grid& grid, OutputStage& stage)
    : w_(w), open_(std::make_unique<Open>()) {
  ensureGdalRegistered();
  const std::string format = w.format.empty() ? driverForPath(w.path) : w.format;
  if (format != "GTiff" && format != "COG") {
    throw Error(w.path + ": a raster written by tiles is a GeoTIFF (GTiff) or a cloud-optimized GeoTIFF (COG), not " +
                format);
  }
  if (grid.blockSize < 16 || grid.blockSize % 16 != 0) {
    throw Error(w.path + ": blocks of " + std::to_string(grid.blockSize) + " pixels; a GeoTIFF's are a multiple of 16");
  }
  Open& o = *open_;
  o.cog = format == "COG";
  o.type = w.byteData ? GDT_Byte : GDT_Float32;
  o.staged = stage.stage(w.path);
  o.tiff = o.cog ? std::filesystem::path(o.staged.string() + ".tiles.tif") : o.staged;
  const std::uint64_t bytes = static_cast<std::uint64_t>(grid.width) * grid.height * (w.byteData ? 1 : 4);
  CPLStringList co;
  co.SetNameValue("TILED", "YES");
  co.SetNameValue("BLOCKXSIZE", std::to_string(grid.blockSize).c_str());
  co.SetNameValue("BLOCKYSIZE", std::to_string(grid.blockSize).c_str());
  co.SetNameValue("COMPRESS", "DEFLATE");
  co.SetNameValue("BIGTIFF", bytes > (3ull << 30) ? "YES" : "IF_SAFER");
  if (!o.cog) overrideWith(w.creationOptions, co);
  GDALDriver* gtiff = GetGDALDriverManager()->GetDriverByName("GTiff");
  o.ds.reset(gtiff->Create(o.tiff.c_str(), grid.width, grid.height, 1, o.type, co.List()));
  if (!o.ds) throw Error(w.path + ": cannot create (" + o.errors.message() + ")");
  double gt[6];
  std::copy(grid.geotransform.begin(), grid.geotransform.end(), gt);
  o.ds->SetGeoTransform(gt);
  if (!grid.crsWkt.empty()) o.ds->SetProjection(grid.crsWkt.c_str());
  for (const auto& [name, value] : grid.metadata) o.ds->SetMetadataItem(name.c_str(), value.c_str());
  o.band = o.ds->GetRasterBand(1);
  if (grid.nodata) o.band->SetNoDataValue(*grid.nodata);
  if (!grid.bandDescription.empty()) o.band->SetDescription(grid.bandDescription.c_str());
  if (!grid.bandUnit.empty()) o.band->SetUnitType(grid.bandUnit.c_str());
}

StreamedRaster::~StreamedRaster() = default;

void StreamedRaster::write(int col, int row, int width, int height, const std::vector<double>& values) {
  Open& o = *open_;
  if (!o.band) throw Error(w_.path + ": written after it was finished");
  if (values.size() != static_cast<std::size_t>(width) * height) throw Error(w_.path + ": a window of the wrong size");
  if (o.band->RasterIO(GF_Write, col, row, width, height, const_cast<double*>(values.data()), width, height,
                       GDT_Float64, 0, 0) != CE_None ||
      o.errors.failed()) {
    throw Error(w_.path + ": cannot write (" + o.errors.message() + ")");
  }
}

void StreamedRaster::setMetadata(const std::vector<std::pair<std::string, std::string>>& items) {
  Open& o = *open_;
  if (!o.ds) throw Error(w_.path + ": metadata set after it was finished");
  for (const auto& [name, value] : items) o.ds->SetMetadataItem(name.c_str(), value.c_str());
}

void StreamedRaster::finish() {
  Open& o = *open_;
  o.band = nullptr;
  o.ds->FlushCache(true);
  o.ds.reset();  // closes it: a failure shows in the error log
  if (o.errors.failed()) throw Error(w_.path + ": cannot write (" + o.errors.message() + ")");
  if (!o.cog) return;
  std::unique_ptr<GDALDataset> tiles(GDALDataset::Open(o.tiff.c_str(), GDAL_OF_RASTER));
  CPLStringList co;
  co.SetNameValue("COMPRESS", "DEFLATE");
  co.SetNameValue("BIGTIFF", "IF_SAFER");
  overrideWith(w_.creationOptions, co);
  GDALDriver* cog = GetGDALDriverManager()->GetDriverByName("COG");
  std::unique_ptr<GDALDataset> copy(
      tiles ? cog->CreateCopy(o.staged.c_str(), tiles.get(), FALSE, co.List(), GDALDummyProgress, nullptr) : nullptr);
  const bool made = copy != nullptr;
  copy.reset();
  tiles.reset();
  std::error_code ec;
  std::filesystem::remove(o.tiff, ec);
  if (!made || o.errors.failed()) throw Error(w_.path + ": cannot write the COG (" + o.errors.message() + ")");
}

}  // namespace qota::tools
