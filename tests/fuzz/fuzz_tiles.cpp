// Tiled shadows' inputs from other processes: a tiles state, and the metadata (or the bytes) of
// tiles given to qota assemble. Any bytes: no crash, no hang, and never a wrong answer with exit
// 0 (an assembled raster must equal the whole run's, the oracle made once at start).
//
// The first byte chooses what the rest is:
//   0: a state's text, read as it is (ShadowTiles::restore, then the calls a job makes on it);
//   1: the same with its checksum made again, so that the values' own checks are reached;
//   2: metadata lines NAME=VALUE set on one of four tiles (the second byte picks it, and whether
//      the seal is made again as a forger would), then qota assemble of the four;
//   3: the bytes of the first tile's file, then qota assemble of the four.
#include <gdal_priv.h>

#include <cmath>
#include <sstream>

#include "fuzz_common.hpp"
#include "qota/error.hpp"
#include "qota/height_blocks.hpp"
#include "qota/shadow_tiles.hpp"
#include "qota_tools.hpp"
#include "tile_metadata.hpp"

namespace {

namespace fs = std::filesystem;

// A 40 x 40 DEM (a ridge and a pit), its whole shadow, its state, and its four tiles of 32.
struct Run {
  std::string dem, state;
  std::vector<std::string> tiles;
  std::vector<std::uint8_t> whole;
};

std::vector<std::uint8_t> readBand(const std::string& path) {
  std::unique_ptr<GDALDataset> ds(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER));
  if (!ds) return {};
  std::vector<std::uint8_t> v(static_cast<std::size_t>(ds->GetRasterXSize()) * ds->GetRasterYSize());
  if (ds->GetRasterBand(1)->RasterIO(GF_Read, 0, 0, ds->GetRasterXSize(), ds->GetRasterYSize(), v.data(),
                                     ds->GetRasterXSize(), ds->GetRasterYSize(), GDT_Byte, 0, 0) != CE_None) {
    return {};
  }
  return v;
}

const Run& run() {
  static const Run r = [] {
    qota::ensureGdalRegistered();
    CPLSetConfigOption("CPL_LOG", "/dev/null");
    Run out;
    const fs::path dir = qota::fuzz::scratch() / "run";
    fs::create_directories(dir);
    out.dem = (dir / "dem.tif").string();
    std::unique_ptr<GDALDataset> ds(
        GetGDALDriverManager()->GetDriverByName("GTiff")->Create(out.dem.c_str(), 40, 40, 1, GDT_Float32, nullptr));
    double gt[6] = {500000, 30, 0, 5100000, 0, -30};
    ds->SetGeoTransform(gt);
    std::vector<float> z(1600);
    for (int r = 0; r < 40; ++r) {
      for (int c = 0; c < 40; ++c)
        z[r * 40 + c] = 500 + 300 * std::exp(-std::pow((c - 20) / 4.0, 2)) -
                        200 * std::exp(-((c - 30) * (c - 30) + (r - 10) * (r - 10)) / 20.0);
    }
    if (ds->GetRasterBand(1)->RasterIO(GF_Write, 0, 0, 40, 40, z.data(), 40, 40, GDT_Float32, 0, 0) != CE_None)
      qota::fuzz::fail("cannot write the DEM");
    ds.reset();
    std::ostringstream sink;
    qota::tools::ShadowOptions o;
    o.source = out.dem, o.azimuth = 100, o.altitude = 8, o.pixelSize = 30, o.quiet = true;
    o.output = (dir / "whole.tif").string();
    qota::tools::shadow(o, sink, sink);
    out.whole = readBand(o.output);
    out.state = (dir / "run.state").string();
    o.tilesState = out.state, o.tileSize = 32;
    for (int r = 0; r < 2; ++r) {
      for (int c = 0; c < 2; ++c) {
        o.tile = std::array<int, 2>{c, r};
        o.output = (dir / ("t_" + std::to_string(c) + "_" + std::to_string(r) + ".tif")).string();
        qota::tools::shadow(o, sink, sink);
        out.tiles.push_back(o.output);
      }
    }
    if (out.whole.size() != 1600 || !fs::exists(out.state)) qota::fuzz::fail("the run's shadow or state is missing");
    return out;
  }();
  return r;
}

// Assembles `tiles`: exit 0 only with the whole run's pixels.
void assembleChecked(const std::vector<std::string>& tiles) {
  const std::string output = (qota::fuzz::scratch() / "assembled.tif").string();
  std::error_code ec;
  fs::remove(output, ec);
  qota::tools::AssembleOptions a;
  a.tiles = tiles, a.output = output, a.quiet = true;
  std::ostringstream out, err;
  if (qota::tools::assemble(a, out, err) != 0) return;
  const std::vector<std::uint8_t> assembled = readBand(output);
  if (assembled != run().whole) {  // a wrong answer with exit 0
    std::size_t differ = 0;
    for (std::size_t i = 0; i < std::min(assembled.size(), run().whole.size()); ++i)
      differ += assembled[i] != run().whole[i];
    qota::fuzz::fail("qota assemble exited 0 with " + std::to_string(assembled.size()) + " pixels, " +
                     std::to_string(differ) + " of them not the whole run's");
  }
}

void useState(const std::string& text) {
  try {
    const qota::ShadowTiles t = qota::ShadowTiles::restore(text);
    const Eigen::Vector3d light(0.7, 0.1, 0.3);
    const qota::DemTerrain& d = t.dem();
    const qota::PixelWindow tile{0, 0, std::min(d.width, 8), std::min(d.height, 8)};
    (void)t.haloFor(8, 8, {light});
    (void)t.largestWindowPixels({tile}, {light});
    const qota::PixelWindow window = t.checkableWindow(tile);
    if (window.pixelCount() <= 4096) {
      (void)t.maskFromHeights(window, std::vector<double>(window.pixelCount(), 500.0), tile, light);
    }
  } catch (const qota::Error&) {
  }
  // As a job restores it, against the raster on disk.
  try {
    qota::DemOptions dem;
    qota::FrameOptions frame;
    frame.pixelSize = 30;
    const qota::ShadowTiles t = qota::ShadowTiles::restore(text, run().dem, dem, frame);
    (void)t.mask({0, 0, 32, 32}, Eigen::Vector3d(0.98, -0.17, 0.14));
  } catch (const qota::Error&) {
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const Run& r = run();
  qota::fuzz::Bytes in(data, size);
  const int mode = in.byte() % 4;
  if (mode == 0 || mode == 1) {
    std::string text(in.rest());
    if (mode == 1) {
      const std::size_t at = text.rfind("checksum ");
      const std::string body = at == std::string::npos ? text : text.substr(0, at);
      text = body + "checksum " + qota::checksumOf(body) + "\n";
    }
    useState(text);
    return 0;
  }
  // Fresh copies of the four tiles, one of them changed.
  const fs::path dir = qota::fuzz::scratch() / "tiles";
  std::error_code ec;
  fs::remove_all(dir, ec);
  if (!fs::create_directories(dir, ec) || ec) qota::fuzz::fail("cannot make " + dir.string() + ": " + ec.message());
  std::vector<std::string> tiles;
  for (const std::string& t : r.tiles) {
    tiles.push_back((dir / fs::path(t).filename()).string());
    qota::fuzz::copyFile(t, tiles.back());
  }
  if (mode == 2) {
    const int pick = in.byte();
    const bool reseal = pick & 4;
    std::unique_ptr<GDALDataset> ds(GDALDataset::Open(tiles[pick % 4].c_str(), GDAL_OF_RASTER | GDAL_OF_UPDATE));
    if (!ds) return 0;
    std::istringstream lines{std::string(in.rest())};
    for (std::string line; std::getline(lines, line);) {
      const auto eq = line.find('=');
      if (eq != std::string::npos && eq > 0)
        ds->SetMetadataItem(line.substr(0, eq).c_str(), line.substr(eq + 1).c_str());
    }
    if (reseal) {
      try {
        const auto sealed = qota::tools::sealTile(qota::tools::qotaItemsOf(*ds), qota::tools::tileGridOf(*ds));
        ds->SetMetadataItem("QOTA_CHECKSUM", sealed.back().second.c_str());
      } catch (const qota::Error&) {
      }
    }
  } else {
    const std::string_view bytes = in.rest();
    std::ofstream(tiles[0], std::ios::binary | std::ios::trunc)
        .write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  }
  assembleChecked(tiles);
  return 0;
}
