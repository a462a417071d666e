// Rasters through GDAL's memory file system: the first byte picks a structured raster (size, data
// type, geotransform, CRS, nodata, scale, unit and pixels all from the input: odd geotransforms,
// tiny and huge sizes, NaN and infinite values) or raw bytes read by a GDAL driver chosen by
// extension. Every raster goes through loadDem and the index, and through the tools: sample
// (checked: one output line per input line), info, shadow (checked: an output exactly when the
// exit code is 0) and build with its tree file sampled back.
#include <gdal_priv.h>
#include <ogr_spatialref.h>

#include <array>
#include <cstdlib>
#include <cmath>
#include <cstring>
#include <memory>
#include <sstream>

#include "fuzz_common.hpp"
#include "qota/dem.hpp"
#include "qota/error.hpp"
#include "qota/terrain.hpp"
#include "qota/treefile.hpp"
#include "qota_tools.hpp"
#include "text_output.hpp"

namespace {

using qota::fuzz::Bytes;

const char* const kMarsWkt =
    "GEOGCS[\"Mars 2000\",DATUM[\"D_Mars_2000\",SPHEROID[\"Mars_2000_IAU_IAG\",3396190,169.894447223612]],"
    "PRIMEM[\"Reference_Meridian\",0],UNIT[\"Degree\",0.0174532925199433]]";

// The structured raster, written to /vsimem; "" when GDAL refuses to make it.
std::string structuredRaster(Bytes& in) {
  qota::ensureGdalRegistered();
  const std::uint8_t shape = in.byte();
  int w = 1 + static_cast<int>(in.u32() % 48), h = 1 + static_cast<int>(in.u32() % 48);
  // Long strips and slivers; up to 1000 pixels, as the sanitizers make a sliver globe's curved
  // tree (some 20 nodes a triangle) cost 2 GB and 30 s an input at 2000.
  if (shape % 16 == 1) w = 1 + static_cast<int>(in.u32() % 1000);
  if (shape % 16 == 2) h = 1 + static_cast<int>(in.u32() % 1000);
  // Declared huge and sparse: far more than any machine's memory, to be refused before reading
  // (sizes in between are real work, not a fuzzer's).
  const bool huge = shape % 16 == 3;
  if (huge) w = 200000 + static_cast<int>(in.u32() % 100000), h = 200000 + static_cast<int>(in.u32() % 100000);
  static constexpr std::array<GDALDataType, 8> kTypes = {GDT_Byte,    GDT_Int16,   GDT_UInt16, GDT_Int32,
                                                         GDT_Float32, GDT_Float64, GDT_CInt16, GDT_CFloat64};
  const GDALDataType type = kTypes[in.byte() % kTypes.size()];
  double gt[6] = {500000, 30, 0, 5000000, 0, -30};
  switch (in.byte() % 5) {
    case 1:
      gt[0] = -121, gt[1] = 1.0 / 120, gt[3] = 47, gt[5] = -1.0 / 120;
      break;
    case 2:
      for (double& g : gt) g = in.f64();
      break;
    case 3:
      gt[2] = 10, gt[4] = 20;
      break;  // rotated
    case 4:
      gt[0] = -180, gt[1] = 360.0 / w, gt[3] = 90, gt[5] = -180.0 / h;
      break;  // the globe
    default:
      break;
  }
  const std::uint8_t crs = in.byte();
  const std::uint8_t extras = in.byte();
  const double nodata = in.f64(), scale = in.f64(), offset = in.f64();
  static constexpr std::array<const char*, 6> kUnits = {"", "m", "ft", "US survey foot", "degC", "\xff\x01"};
  const char* unit = kUnits[(extras >> 4) % kUnits.size()];

  const std::string path = "/vsimem/fuzz_raster.tif";
  GDALDriver* tiff = GetGDALDriverManager()->GetDriverByName("GTiff");
  char** co = nullptr;
  if (huge) co = CSLSetNameValue(CSLSetNameValue(co, "SPARSE_OK", "TRUE"), "TILED", "YES");
  co = CSLSetNameValue(co, "BIGTIFF", "IF_SAFER");
  std::unique_ptr<GDALDataset> ds(tiff->Create(path.c_str(), w, h, 1 + (extras & 1), type, co));
  CSLDestroy(co);
  if (!ds) return "";
  ds->SetGeoTransform(gt);
  OGRSpatialReference srs;
  const int which = crs % 7;
  if (which == 1) srs.SetFromUserInput("EPSG:4326");
  if (which == 2) srs.SetFromUserInput("EPSG:32610");
  if (which == 3) srs.SetFromUserInput(kMarsWkt);
  if (which == 4) srs.SetFromUserInput("EPSG:4326+5703");
  if (which == 5) srs.SetFromUserInput("EPSG:3857");
  if (which >= 1 && which <= 5) ds->SetSpatialRef(&srs);
  GDALRasterBand* band = ds->GetRasterBand(1);
  if (extras & 2) band->SetNoDataValue(nodata);
  if (extras & 4) band->SetScale(scale);
  if (extras & 8) band->SetOffset(offset);
  if (*unit) band->SetUnitType(unit);
  if (!huge) {
    const std::string_view pixels = in.rest();
    const int bytes = GDALGetDataTypeSizeBytes(type);
    std::vector<std::uint8_t> buffer(static_cast<std::size_t>(w) * h * bytes);
    for (std::size_t i = 0; i < buffer.size() && !pixels.empty(); ++i)
      buffer[i] = static_cast<std::uint8_t>(pixels[i % pixels.size()]);
    if (band->RasterIO(GF_Write, 0, 0, w, h, buffer.data(), w, h, type, 0, 0) != CE_None) return "";
  }
  return path;
}

std::string rawRaster(Bytes& in) {
  static constexpr std::array<const char*, 6> kExtensions = {".tif", ".asc", ".xyz", ".hgt", ".vrt", ".grd"};
  const std::string path = std::string("/vsimem/fuzz_raw") + kExtensions[in.byte() % kExtensions.size()];
  const std::string_view bytes = in.rest();
  VSILFILE* f = VSIFOpenL(path.c_str(), "wb");
  if (!f) return "";
  VSIFWriteL(bytes.data(), 1, bytes.size(), f);
  VSIFCloseL(f);
  return path;
}

std::size_t linesIn(const std::string& s) {
  std::size_t n = 0;
  for (char c : s) n += c == '\n';
  return n + (!s.empty() && s.back() != '\n');
}

void runTools(const std::string& path, std::uint8_t how) {
  std::ostringstream out, err;
  // sample: the corners, the centre, outside, in the raster's own coordinates when they are known.
  qota::tools::SampleOptions s;
  s.source = path;
  s.mapping = how % 3 == 1 ? "geodetic" : how % 3 == 2 ? "spherical" : "";
  s.queryZ = how & 8;
  std::string points;
  try {
    const qota::DemTerrain d = qota::describeDem(path, {.band = 1, .lonLatAsCartesian = true});
    for (const auto& [c, r] : {std::pair{0.0, 0.0},
                               {d.width * 1.0, d.height * 1.0},
                               {d.width / 2.0, d.height / 2.0},
                               {-1.0, -1.0},
                               {0.25, d.height - 0.25}}) {
      const auto xy = d.pixelCentre(c - 0.5, r - 0.5);
      points += qota::tools::formatNumber(xy[0]) + " " + qota::tools::formatNumber(xy[1]) + " 1e9\n";
    }
  } catch (const qota::Error&) {
    points = "1 2\n";
  }
  s.band = 1;
  std::istringstream in(points);
  const int code = qota::tools::sample(s, in, out, err);
  if (code < 0 || code > 2 || (code != 2 && linesIn(out.str()) != linesIn(points))) std::abort();

  qota::tools::InfoOptions i;
  i.source.source = path;
  i.source.band = 1;
  {
    // --stats reads every pixel a header declares (as gdalinfo -stats does): a few bytes can
    // declare billions, so only rasters of a few million pixels are read here.
    std::unique_ptr<GDALDataset> probe(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER));
    i.stats = probe && static_cast<double>(probe->GetRasterXSize()) * probe->GetRasterYSize() <= 4e6;
  }
  if (int c = qota::tools::info(i, out, err); c != 0 && c != 2) std::abort();
  i.tree = true, i.json = true;
  if (int c = qota::tools::info(i, out, err); c != 0 && c != 2) std::abort();

  qota::tools::ShadowOptions sh;
  sh.source = path;
  sh.band = 1;
  sh.output = (qota::fuzz::scratch() / "shadow.tif").string();
  std::filesystem::remove(sh.output);
  sh.quiet = true;
  sh.flat = how & 16;

  sh.pixelSize = 10;
  if (how & 64) {
    sh.time = "2024-06-21T" + std::to_string(how % 24 < 10 ? 0 : 1) + std::to_string(how % 10) + ":00Z";
  } else {
    sh.azimuth = how * 7.0, sh.altitude = (how % 90) - 5.0;
  }
  // A raster declared huge is real work by tiles (hours of it): here only what is refused before
  // the work starts, a tile off the tile grid.
  bool huge = false;
  double cells = 0;
  try {
    const qota::DemTerrain d = qota::describeDem(path, {.band = 1, .lonLatAsCartesian = true});
    cells = static_cast<double>(d.width) * d.height;
    huge = cells > double(1 << 22);
  } catch (const qota::Error&) {
  }
  if (huge) sh.tileSize = 64, sh.tile = std::array<int, 2>{-1, static_cast<int>(how)};
  // The shadow quadtree on small rasters only: on wild relief (30 km cliffs between 10 m pixels,
  // which the fuzzer makes at will) each ray tests hundreds of the light frame's overlapping
  // slivers, 2.6 s for 48,000 cells in a release build and minutes under the sanitizers. That is
  // the search's real cost there (the strips, the default, take 0.2 s), not a hang.
  sh.search = how & 32 && cells <= 8192 ? qota::ShadowSearch::Quadtree : qota::ShadowSearch::Strips;
  const int sc = qota::tools::shadow(sh, out, err);
  if (huge && sc == 0) std::abort();
  if ((sc == 0) != std::filesystem::exists(sh.output) || (sc != 0 && sc != 2)) std::abort();

  qota::tools::BuildOptions b;
  b.source.source = path;
  b.source.band = 1;
  b.source.mapping = s.mapping;
  b.output = (qota::fuzz::scratch() / "tree.qota").string();
  std::filesystem::remove(b.output);
  b.quiet = true;
  const int bc = qota::tools::build(b, out, err);
  if ((bc == 0) != std::filesystem::exists(b.output) || (bc != 0 && bc != 2)) std::abort();
  if (bc == 0) {
    s.source = b.output;
    s.mapping.clear();
    s.band = 0;
    std::istringstream again(points);
    const int tc = qota::tools::sample(s, again, out, err);
    if (tc < 0 || tc > 2 || (tc != 2 && linesIn(out.str()) < 1)) std::abort();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  // GDAL's block cache would grow to 5% of the machine's memory over thousands of rasters, past
  // the fuzzer's memory limit: keep it small.
  static const bool cacheSet = [] {
    GDALSetCacheMax64(64ll << 20);
    return true;
  }();
  (void)cacheSet;
  Bytes in(data, size);
  const std::uint8_t mode = in.byte(), how = in.byte();
  const std::string path = mode < 192 ? structuredRaster(in) : rawRaster(in);
  if (path.empty()) return 0;
  if (const char* dump = std::getenv("QOTA_FUZZ_DUMP")) {  // to look at an input's raster with GDAL's tools
    GDALDriver* tiff = GetGDALDriverManager()->GetDriverByName("GTiff");
    std::unique_ptr<GDALDataset> src(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER));
    if (src) std::unique_ptr<GDALDataset>(tiff->CreateCopy(dump, src.get(), FALSE, nullptr, nullptr, nullptr));
  }
  try {
    const qota::DemTerrain dem = qota::loadDem(path, {.band = 1, .lonLatAsCartesian = true});
    const qota::CartesianIndex index(dem.mesh, dem.mapping);
    for (int r = 0; r < std::min(dem.height, 4); ++r) {
      const auto xy = dem.pixelCentre(r * 0.7, r * 0.3);
      (void)index.topWorld({xy[0], xy[1], 0});
    }
  } catch (const qota::Error&) {
  }
  runTools(path, how);
  VSIUnlink(path.c_str());
  return 0;
}
