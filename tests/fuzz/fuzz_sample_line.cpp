// qota sample's line reader: the first bytes pick the options, the rest is the input text, read
// against a small raster. Checked: the exit code is 0, 1 or 2, and unless it is 2 the output has
// one line for every input line.
#include <gdal_priv.h>

#include <cstdio>
#include <sstream>

#include "fuzz_common.hpp"
#include "qota/dem.hpp"
#include "qota_tools.hpp"

namespace {

// A 20 x 15 raster in lon/lat with a void, made once in GDAL's memory file system.
const char* demPath() {
  static const char* path = [] {
    qota::ensureGdalRegistered();
    const char* p = "/vsimem/fuzz_sample.tif";
    GDALDriver* drv = GetGDALDriverManager()->GetDriverByName("GTiff");
    std::unique_ptr<GDALDataset> ds(drv->Create(p, 20, 15, 1, GDT_Float32, nullptr));
    double gt[6] = {-121.0, 0.01, 0, 46.5, 0, -0.01};
    ds->SetGeoTransform(gt);
    OGRSpatialReference srs;
    srs.SetFromUserInput("EPSG:4326");
    ds->SetSpatialRef(&srs);
    std::vector<float> z(300);
    for (int i = 0; i < 300; ++i) z[i] = static_cast<float>(1000 + 37 * (i % 7) - 11 * (i % 13));
    z[77] = -9999;
    ds->GetRasterBand(1)->SetNoDataValue(-9999);
    if (ds->GetRasterBand(1)->RasterIO(GF_Write, 0, 0, 20, 15, z.data(), 20, 15, GDT_Float32, 0, 0) != CE_None) {
      std::abort();
    }
    return p;
  }();
  return path;
}

// The lines qota sample reads in `text`: a leading byte-order mark is not part of the first
// line, and a text with carriage returns but no newline ends its lines with them (classic Mac OS).
std::size_t linesIn(std::string s) {
  if (s.starts_with("\xEF\xBB\xBF")) s.erase(0, 3);
  const char end = s.find('\n') == std::string::npos && s.find('\r') != std::string::npos ? '\r' : '\n';
  std::size_t n = 0;
  for (char c : s) n += c == end;
  return n + (!s.empty() && s.back() != end);
}

std::size_t linesOut(const std::string& s) {
  std::size_t n = 0;
  for (char c : s) n += c == '\n';
  return n + (!s.empty() && s.back() != '\n');
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  qota::fuzz::Bytes in(data, size);
  qota::tools::SampleOptions o;
  o.source = demPath();
  const std::uint8_t flags = in.byte();
  o.queryZ = flags & 1;
  o.header = flags & 2;
  o.swapXY = flags & 4;
  o.printWorld = flags & 8;
  if (flags & 16) o.mapping = "geodetic";
  if (flags & 32) o.srs = "EPSG:32610";
  const std::uint8_t p = in.byte();
  o.precision = p < 128 ? p - 5 : -1;  // -5 .. 122: below, inside and above the allowed range
  const std::string text(in.rest());
  std::istringstream input(text);
  std::ostringstream out, err;
  const int code = qota::tools::sample(o, input, out, err);
  if (code < 0 || code > 2) std::abort();
  if (code != 2 && linesOut(out.str()) != linesIn(text)) {
    std::fprintf(stderr, "%zu lines in, %zu out\n", linesIn(text), linesOut(out.str()));
    std::abort();
  }
  return 0;
}
