// The qota command line: the input is the argument list (arguments separated by NUL or newline
// bytes; after a byte 0x01, the rest is stdin), run in a private folder that holds a small DEM,
// a mesh and a tree file under the names dem.tif, mesh.obj and tree.qota. Paths are kept inside
// that folder (a leading '/' and '..' are rewritten), so the fuzzer cannot write elsewhere.
// Checked: the exit code is 0, 1 or 2, and nothing escapes as an exception.
#include <gdal_priv.h>
#include <unistd.h>

#include <sstream>
#include <vector>

#include "fuzz_common.hpp"
#include "qota/dem.hpp"
#include "qota_tools.hpp"

namespace {

void setUp() {
  static const bool done = [] {
    const auto& dir = qota::fuzz::scratch();
    if (::chdir(dir.c_str()) != 0) std::abort();
    qota::ensureGdalRegistered();
    GDALDriver* drv = GetGDALDriverManager()->GetDriverByName("GTiff");
    std::unique_ptr<GDALDataset> ds(drv->Create("dem.tif", 24, 18, 1, GDT_Float32, nullptr));
    double gt[6] = {-121.0, 0.01, 0, 46.5, 0, -0.01};
    ds->SetGeoTransform(gt);
    OGRSpatialReference srs;
    srs.SetFromUserInput("EPSG:4326");
    ds->SetSpatialRef(&srs);
    std::vector<float> z(24 * 18);
    for (std::size_t i = 0; i < z.size(); ++i) z[i] = static_cast<float>(900 + 53 * (i % 5) - 17 * (i % 11));
    if (ds->GetRasterBand(1)->RasterIO(GF_Write, 0, 0, 24, 18, z.data(), 24, 18, GDT_Float32, 0, 0) != CE_None) {
      std::abort();
    }
    ds.reset();
    std::ofstream("mesh.obj") << "v 0 0 1\nv 10 0 2\nv 10 10 3\nv 0 10 4\nf 1 2 3 4\n";
    const char* args[] = {"qota", "build", "dem.tif", "-o", "tree.qota", "-q"};
    std::istringstream in;
    std::ostringstream out, err;
    if (qota::tools::runCli(6, args, in, out, err) != 0) std::abort();
    return true;
  }();
  (void)done;
}

// Keeps a path argument inside the folder.
std::string confined(std::string arg) {
  for (std::size_t p; (p = arg.find("..")) != std::string::npos;) arg.replace(p, 2, "__");
  if (!arg.empty() && arg[0] == '/' && arg.rfind("/vsimem/", 0) != 0) arg[0] = '_';
  for (const char* risky : {"/vsicurl", "/vsis3", "/vsigs", "/vsiaz", "/vsioss", "/vsiswift", "/vsihdfs", "/vsiwebhdfs",
                            "/vsistdin", "/vsistdout"}) {
    for (std::size_t p; (p = arg.find(risky)) != std::string::npos;) arg[p] = '_';
  }
  return arg;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  setUp();
  const std::string text(reinterpret_cast<const char*>(data), size);
  const std::size_t split = text.find('\x01');
  const std::string argText = text.substr(0, split),
                    stdinText = split == std::string::npos ? "" : text.substr(split + 1);
  std::vector<std::string> args{"qota"};
  std::string current;
  for (char c : argText) {
    if (c == '\0' || c == '\n') {
      args.push_back(confined(current));
      current.clear();
    } else {
      current += c;
    }
  }
  if (!current.empty()) args.push_back(confined(current));
  if (args.size() > 64) return 0;
  std::vector<const char*> argv;
  for (const auto& a : args) argv.push_back(a.c_str());
  std::istringstream in(stdinText);
  std::ostringstream out, err;
  const int code = qota::tools::runCli(static_cast<int>(argv.size()), argv.data(), in, out, err);
  if (code < 0 || code > 2) std::abort();
  return 0;
}
