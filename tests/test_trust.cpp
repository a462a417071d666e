// What tiled shadows trust and must check: a tiles state made for another raster, band or frame,
// or edited; a state path that is not a file; tiles of another run, forged or damaged tiles given
// to qota assemble. Each case answered wrong with exit 0 before; each must now be refused, by
// name, with nothing written. The expected values are the whole raster's shadows (qota shadow
// without tiles, itself held to the brute-force oracle in test_shadow.cpp).
#include <gdal_priv.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>

#include "qota/height_blocks.hpp"
#include "qota_tools.hpp"
#include "raster_files.hpp"
#include "tile_metadata.hpp"

namespace {

namespace fs = std::filesystem;
using qota::test::RasterSpec;
using qota::test::scratchPath;
using qota::tools::ShadowOptions;

struct ToolRun {
  int code;
  std::string out, err;
};

ToolRun shadow(const ShadowOptions& o) {
  std::ostringstream out, err;
  const int code = qota::tools::shadow(o, out, err);
  return {code, out.str(), err.str()};
}

ToolRun assemble(const std::vector<std::string>& tiles, const std::string& output) {
  qota::tools::AssembleOptions a;
  a.tiles = tiles;
  a.output = output;
  a.quiet = true;
  std::ostringstream out, err;
  const int code = qota::tools::assemble(a, out, err);
  return {code, out.str(), err.str()};
}

// Mount St. Helens (data/SainteHelens.dem) as a Float32 GeoTIFF, and rasters on the same grid with
// other heights: 700 m everywhere, and two bands (the flat one, then the DEM).
struct HelensFiles {
  std::string dem, flat, twoBands;
};

const HelensFiles& helens() {
  static const HelensFiles files = [] {
    qota::ensureGdalRegistered();
    const qota::test::RasterValues r = qota::test::readRaster(QOTA_DATA_DIR "/SainteHelens.dem");
    std::unique_ptr<GDALDataset> src(GDALDataset::Open(QOTA_DATA_DIR "/SainteHelens.dem", GDAL_OF_RASTER));
    RasterSpec s;
    s.width = r.width, s.height = r.height, s.geotransform = r.geotransform;
    s.crs = src->GetProjectionRef();
    s.nodata = -32767;
    s.type = GDT_Float32;
    const std::vector<double> flat(r.values.size(), 700.0);
    HelensFiles f;
    fs::create_directories(scratchPath("trust"));
    f.dem = scratchPath("trust/sh.tif").string();
    f.flat = scratchPath("trust/flat.tif").string();
    f.twoBands = scratchPath("trust/twoband.tif").string();
    // Written under this process's name, then renamed: ctest runs tests in parallel processes.
    const auto write = [&](const std::string& path, std::vector<std::vector<double>> bands) {
      s.bands = std::move(bands);
      const std::string mine = path + "." + std::to_string(::getpid());
      qota::test::writeRaster(mine, s);
      fs::rename(mine, path);
    };
    write(f.dem, {r.values});
    write(f.flat, {flat});
    write(f.twoBands, {flat, r.values});
    return f;
  }();
  return files;
}

ShadowOptions at(const std::string& source, const std::string& output, double azimuth = 90, double altitude = 5) {
  ShadowOptions o;
  o.source = source;
  o.output = scratchPath(output).string();
  o.quiet = true;
  o.azimuth = azimuth, o.altitude = altitude;
  fs::remove(o.output);
  return o;
}

void expectRefused(const ToolRun& run, const std::string& why, const std::string& output) {
  EXPECT_EQ(run.code, 2) << run.err;
  EXPECT_NE(run.err.find(why), std::string::npos) << "expected '" << why << "' in: " << run.err;
  EXPECT_FALSE(fs::exists(output)) << output;
}

std::string readFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

void writeFile(const std::string& path, const std::string& text) { std::ofstream(path, std::ios::binary) << text; }

// A state with its checksum made again after an edit: only the values' own checks stand.
std::string resealed(std::string state) {
  state = state.substr(0, state.rfind("checksum "));
  return state + "checksum " + qota::checksumOf(state) + "\n";
}

TEST(TrustState, AnotherRastersOrBandsStateIsRefused) {
  const HelensFiles& f = helens();
  const std::string flatState = scratchPath("trust/flat.state").string();
  fs::remove(flatState);
  ShadowOptions o = at(f.flat, "trust/flat_tiled.tif");
  o.tileSize = 64, o.tilesState = flatState;
  ASSERT_EQ(shadow(o).code, 0);
  // The DEM on the same grid, with the flat raster's state: its heights are not the state's.
  o = at(f.dem, "trust/dem_with_flat_state.tif");
  o.tileSize = 64, o.tilesState = flatState;
  expectRefused(shadow(o), "are not those the shadow tiles were made from", o.output);
  // Band 1's state for band 2.
  const std::string bandState = scratchPath("trust/band1.state").string();
  fs::remove(bandState);
  o = at(f.twoBands, "trust/band1.tif");
  o.band = 1, o.tileSize = 64, o.tilesState = bandState;
  ASSERT_EQ(shadow(o).code, 0);
  o.band = 2, o.output = scratchPath("trust/band2.tif").string();
  fs::remove(o.output);
  expectRefused(shadow(o), "its band differs (the state's 1, this raster's 2)", o.output);
}

TEST(TrustState, EditedOrImpossibleStatesAreRefused) {
  const HelensFiles& f = helens();
  const std::string good = scratchPath("trust/good.state").string();
  fs::remove(good);
  ShadowOptions o = at(f.dem, "trust/good.tif");
  o.tileSize = 64, o.tilesState = good;
  ASSERT_EQ(shadow(o).code, 0);
  const std::string state = readFile(good);
  ASSERT_NE(state.find("\nchecksum "), std::string::npos);
  const std::string bad = scratchPath("trust/bad.state").string();
  o.tilesState = bad;
  o.output = scratchPath("trust/bad.tif").string();
  // Any edit: the checksum no longer holds.
  for (const auto& [field, value] : std::vector<std::pair<std::string, std::string>>{{"maxHeight", "1.5p+9"},
                                                                                     {"maxHeight", "nan"},
                                                                                     {"maxHeight", "inf"},
                                                                                     {"winding", "1p+40"},
                                                                                     {"winding", "-1p+0"},
                                                                                     {"pixelSizeY", "-1p+4"},
                                                                                     {"width", "inf"}}) {
    writeFile(bad, std::regex_replace(state, std::regex("\n" + field + " [^\n]*"), "\n" + field + " " + value));
    fs::remove(o.output);
    expectRefused(shadow(o), "edited or damaged", o.output);
  }
  writeFile(bad, state.substr(0, state.size() / 2));  // cut short
  expectRefused(shadow(o), "edited, damaged or cut short", o.output);
  // Values no raster gives are refused even under a checksum that holds.
  for (const auto& [field, value, why] :
       std::vector<std::array<std::string, 3>>{{"width", "inf", "'width'"},
                                               {"pixelSizeY", "-1p+4", "'pixelSizeY'"},
                                               {"maxHeight", "nan", "height range"},
                                               {"winding", "0p+0", "height range or winding"},
                                               {"winding", "1p+1", "'winding'"},
                                               {"validPixels", "1p+60", "'validPixels'"}}) {
    writeFile(bad,
              resealed(std::regex_replace(state, std::regex("\n" + field + " [^\n]*"), "\n" + field + " " + value)));
    fs::remove(o.output);
    expectRefused(shadow(o), why, o.output);
  }
}

TEST(TrustState, AStatePathThatIsNotAFileIsRefusedAtOnce) {
  const HelensFiles& f = helens();
  const std::string fifo = scratchPath("trust/fifo.state").string();
  fs::remove(fifo);
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  for (const std::string& path : {fifo, std::string("/dev/zero")}) {
    ShadowOptions o = at(f.dem, "trust/fifo.tif");
    o.tileSize = 64, o.tilesState = path;
    expectRefused(shadow(o), "not a regular file", o.output);  // (waited for ever, or read 11 GB, before)
  }
  fs::remove(fifo);
}

// Tiles of one run (the DEM at -az 90 -alt 5, tiles of 128), one job each, sharing one state.
std::vector<std::string> runTiles(const std::string& folder, const std::string& state) {
  const HelensFiles& f = helens();
  fs::remove_all(scratchPath(folder));
  fs::create_directories(scratchPath(folder));
  std::vector<std::string> tiles;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 3; ++c) {
      ShadowOptions o = at(f.dem, folder + "/t_" + std::to_string(c) + "_" + std::to_string(r) + ".tif");
      o.tileSize = 128, o.tile = std::array<int, 2>{c, r}, o.tilesState = state;
      const ToolRun run = shadow(o);
      EXPECT_EQ(run.code, 0) << run.err;
      tiles.push_back(o.output);
    }
  }
  return tiles;
}

TEST(TrustAssemble, TilesOfAnotherRunAreRefusedByTheFieldThatDiffers) {
  const HelensFiles& f = helens();
  const std::string state = scratchPath("trust/run.state").string();
  fs::remove(state);
  const std::vector<std::string> tiles = runTiles("trust/run", state);
  ShadowOptions whole = at(f.dem, "trust/run_whole.tif");
  ASSERT_EQ(shadow(whole).code, 0);
  const std::string joined = scratchPath("trust/run_joined.tif").string();
  fs::remove(joined);
  const ToolRun run = assemble(tiles, joined);
  ASSERT_EQ(run.code, 0) << run.err;
  EXPECT_TRUE(qota::test::readRaster(joined).values == qota::test::readRaster(whole.output).values);

  // Tile 1,1 again from another run; each is refused naming what differs.
  fs::create_directories(scratchPath("trust/other"));
  const auto other = [&](const std::string& why, const std::function<void(ShadowOptions&)>& change) {
    ShadowOptions o = at(f.dem, "trust/other/t_1_1.tif");
    o.tileSize = 128, o.tile = std::array<int, 2>{1, 1};
    change(o);
    const ToolRun made = shadow(o);
    ASSERT_EQ(made.code, 0) << made.err;
    std::vector<std::string> mixed = tiles;
    mixed[4] = o.output;
    const std::string out = scratchPath("trust/mixed.tif").string();
    fs::remove(out);
    expectRefused(assemble(mixed, out), why, out);
  };
  other("light (QOTA_LIGHT)", [](ShadowOptions& o) { o.azimuth = 270; });
  other("light (QOTA_LIGHT)", [](ShadowOptions& o) { o.altitude = 6; });
  other("frame options (QOTA_FRAME)", [](ShadowOptions& o) { o.zFactor = 2; });
  other("output values (QOTA_VALUES)", [](ShadowOptions& o) { o.litValue = 1; });
  other("source heights (QOTA_HEIGHTS)", [&](ShadowOptions& o) {
    // Another DEM under the same file name, on the same grid.
    fs::create_directories(scratchPath("trust/dem2"));
    const std::string renamed = scratchPath("trust/dem2/sh.tif").string();
    fs::copy_file(f.flat, renamed, fs::copy_options::overwrite_existing);
    o.source = renamed;
  });
  // The light as hours of sunlight: another span or step is another run.
  ShadowOptions hours = at(f.dem, "trust/hours_a.tif");
  hours.azimuth.reset(), hours.altitude.reset();
  hours.time = "2024-06-21", hours.tz = "America/Los_Angeles", hours.hours = std::array<double, 3>{6, 20, 2};
  hours.tileSize = 128, hours.tile = std::array<int, 2>{0, 0};
  ASSERT_EQ(shadow(hours).code, 0);
  ShadowOptions hoursB = hours;
  hoursB.output = scratchPath("trust/hours_b.tif").string(), hoursB.tile = std::array<int, 2>{1, 0};
  hoursB.hours = std::array<double, 3>{6, 20, 1};
  ASSERT_EQ(shadow(hoursB).code, 0);
  const std::string out = scratchPath("trust/hours_joined.tif").string();
  fs::remove(out);
  expectRefused(assemble({hours.output, hoursB.output}, out), "light (QOTA_LIGHT)", out);
}

// Sets a tile's QOTA_ items (and, when `seal`, its checksum made again, as a forger would).
void editTile(const std::string& path, const qota::tools::MetadataItems& changes, bool seal) {
  std::unique_ptr<GDALDataset> ds(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER | GDAL_OF_UPDATE));
  ASSERT_TRUE(ds);
  for (const auto& [k, v] : changes) ds->SetMetadataItem(k.c_str(), v.c_str());
  if (!seal) return;
  const auto sealed = qota::tools::sealTile(qota::tools::qotaItemsOf(*ds), qota::tools::tileGridOf(*ds));
  ds->SetMetadataItem("QOTA_CHECKSUM", sealed.back().second.c_str());
}

TEST(TrustAssemble, ForgedGridsAreAnErrorAtOnce) {
  const std::string state = scratchPath("trust/forged.state").string();
  fs::remove(state);
  const std::vector<std::string> tiles = runTiles("trust/forged", state);
  const std::string out = scratchPath("trust/forged.tif").string();
  // A grid of 10^10 tiles declared (it took minutes and gigabytes before): the seal is broken.
  for (const std::string& t : tiles) editTile(t, {{"QOTA_TILES", "100000,100000"}}, false);
  expectRefused(assemble(tiles, out), "damaged or edited", out);
  // Sealed again: the grid does not match the raster and tile sizes.
  for (const std::string& t : tiles) editTile(t, {}, true);
  expectRefused(assemble(tiles, out), "is not the grid of its QOTA_RASTER_SIZE", out);
  // A consistent forgery of a raster of 10^9 x 10^9 pixels: the edge tiles are not the size it
  // says; the full ones are where it says, and the missing tiles are counted, not walked.
  for (const std::string& t : tiles) {
    editTile(t, {{"QOTA_RASTER_SIZE", "1000000000,1000000000"}, {"QOTA_TILES", "7812500,7812500"}}, true);
  }
  expectRefused(assemble(tiles, out), "not where its QOTA_TILE (2,0) puts it", out);
  std::vector<std::string> full;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 2; ++c) full.push_back(tiles[static_cast<std::size_t>(r * 3 + c)]);
  }
  expectRefused(assemble(full, out), "61035156249994 of the run's 61035156250000 tiles are missing (--tile 2,0 3,0",
                out);
}

TEST(TrustAssemble, DamagedTilesAreNamedSo) {
  const std::string state = scratchPath("trust/damaged.state").string();
  fs::remove(state);
  std::vector<std::string> tiles = runTiles("trust/damaged", state);
  const std::string out = scratchPath("trust/damaged.tif").string();
  // One pixel changed (its metadata untouched).
  {
    std::unique_ptr<GDALDataset> ds(GDALDataset::Open(tiles[5].c_str(), GDAL_OF_RASTER | GDAL_OF_UPDATE));
    ASSERT_TRUE(ds);
    std::uint8_t v = 0;
    ASSERT_EQ(ds->GetRasterBand(1)->RasterIO(GF_Read, 10, 10, 1, 1, &v, 1, 1, GDT_Byte, 0, 0), CE_None);
    v = v == 255 ? 0 : 255;
    ASSERT_EQ(ds->GetRasterBand(1)->RasterIO(GF_Write, 10, 10, 1, 1, &v, 1, 1, GDT_Byte, 0, 0), CE_None);
  }
  expectRefused(assemble(tiles, out), "its pixels are not those qota wrote", out);
  // Cut short (a copy interrupted).
  tiles = runTiles("trust/damaged", state);
  fs::resize_file(tiles[7], fs::file_size(tiles[7]) / 2);
  expectRefused(assemble(tiles, out), "damaged", out);
  // A FIFO among the tiles is refused, not waited on.
  const std::string fifo = scratchPath("trust/damaged/fifo.tif").string();
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  tiles[7] = fifo;
  expectRefused(assemble(tiles, out), "not a regular file", out);
}

TEST(TrustAssemble, RotatedTilesCannotMakeAVrtAndSayWhy) {
  const qota::test::RasterValues r = qota::test::readRaster(helens().dem);
  RasterSpec s;
  s.width = r.width, s.height = r.height;
  const double c = std::cos(20 * M_PI / 180), n = std::sin(20 * M_PI / 180);
  s.geotransform = {r.geotransform[0], 30 * c, 30 * n, r.geotransform[3], 30 * n, -30 * c};
  s.crs = "EPSG:32610", s.nodata = -32767, s.type = GDT_Float32, s.bands = {r.values};
  const std::string rotated = scratchPath("trust/rotated.tif").string();
  qota::test::writeRaster(rotated, s);
  fs::remove_all(scratchPath("trust/rot"));
  fs::create_directories(scratchPath("trust/rot"));
  std::vector<std::string> tiles;
  for (int row = 0; row < 2; ++row) {
    for (int col = 0; col < 2; ++col) {
      ShadowOptions o = at(rotated, "trust/rot/t_" + std::to_string(col) + "_" + std::to_string(row) + ".tif", 90, 3);
      o.tileSize = 256, o.tile = std::array<int, 2>{col, row};
      const ToolRun run = shadow(o);
      ASSERT_EQ(run.code, 0) << run.err;
      tiles.push_back(o.output);
    }
  }
  const std::string vrt = scratchPath("trust/rot.vrt").string();
  fs::remove(vrt);
  expectRefused(assemble(tiles, vrt), "a VRT mosaic holds north-up tiles only, and these are rotated", vrt);
  const std::string tif = scratchPath("trust/rot.tif").string();
  EXPECT_EQ(assemble(tiles, tif).code, 0);
}

}  // namespace

namespace {

ToolRun sampleLines(const std::string& source, const std::string& input) {
  qota::tools::SampleOptions o;
  o.source = source;
  std::istringstream in(input);
  std::ostringstream out, err;
  const int code = qota::tools::sample(o, in, out, err);
  return {code, out.str(), err.str()};
}

TEST(TrustOutputs, CreationOptionsThatChangeTheValuesAreRefused) {
  const HelensFiles& f = helens();
  for (const std::vector<std::string>& co :
       std::vector<std::vector<std::string>>{{"NBITS=1"},
                                             {"COMPRESS=JPEG"},
                                             {"COMPRESS=WEBP"},
                                             {"COMPRESS=LERC_DEFLATE", "MAX_Z_ERROR=0.5"},
                                             {"PIXELTYPE=SIGNEDBYTE"}}) {
    ShadowOptions o = at(f.dem, "trust/co.tif");
    o.creationOptions = co;
    expectRefused(shadow(o), "the values written would not be the ones computed", o.output);
    o.tileSize = 128;  // by tiles too
    expectRefused(shadow(o), "the values written would not be the ones computed", o.output);
  }
  ShadowOptions hours = at(f.dem, "trust/co_hours.tif");
  hours.azimuth.reset(), hours.altitude.reset();
  hours.time = "2024-06-21", hours.tz = "UTC", hours.hours = std::array<double, 3>{6, 20, 2};
  hours.creationOptions = {"NBITS=16"};  // half floats
  expectRefused(shadow(hours), "hours are 32-bit floats", hours.output);
  // Lossless options pass; an option GDAL does not know is reported as GDAL reports it.
  ShadowOptions o = at(f.dem, "trust/co_ok.tif");
  o.creationOptions = {"COMPRESS=ZSTD", "NBITS=8", "NO_SUCH_OPTION=1"};
  const ToolRun run = shadow(o);
  EXPECT_EQ(run.code, 0) << run.err;
  EXPECT_NE(run.err.find("warning: GDAL: driver GTiff does not support creation option NO_SUCH_OPTION"),
            std::string::npos)
      << run.err;
}

TEST(TrustInput, ARasterOfOneRowOrColumnIsRefusedNotAnsweredNone) {
  RasterSpec s;
  s.geotransform = {500000, 30, 0, 5100000, 0, -30};
  s.type = GDT_Float32;
  for (const auto& [w, h] : std::vector<std::pair<int, int>>{{100, 1}, {1, 100}, {1, 1}}) {
    s.width = w, s.height = h, s.bands = {std::vector<double>(static_cast<std::size_t>(w) * h, 42.0)};
    const std::string path = scratchPath("trust/thin_" + std::to_string(w) + "x" + std::to_string(h) + ".tif").string();
    qota::test::writeRaster(path, s);
    const ToolRun run = sampleLines(path, "500015 5099985\n");  // a pixel centre (none, exit 0 before)
    EXPECT_EQ(run.code, 2) << run.out << run.err;
    EXPECT_NE(run.err.find("at least 2 x 2 pixels"), std::string::npos) << run.err;
  }
}

TEST(TrustInput, AByteOrderMarkAndCarriageReturnLinesAreRead) {
  // 562500 5114500 is on Mount St. Helens's raster; the expected height is the same point's
  // answer from a plain line.
  const ToolRun plain = sampleLines(QOTA_DATA_DIR "/SainteHelens.dem", "562500 5114500\n562501 5114500\n");
  ASSERT_EQ(plain.code, 0) << plain.err;
  const ToolRun bom = sampleLines(QOTA_DATA_DIR "/SainteHelens.dem",
                                  "\xEF\xBB\xBF"
                                  "562500 5114500\n562501 5114500\n");
  EXPECT_EQ(bom.code, 0) << bom.err;
  EXPECT_EQ(bom.out, plain.out);
  const ToolRun cr = sampleLines(QOTA_DATA_DIR "/SainteHelens.dem", "562500 5114500\r562501 5114500\r");
  EXPECT_EQ(cr.code, 0) << cr.err;
  EXPECT_EQ(cr.out, plain.out);
  // What a terminal would not show is written as escapes in a message.
  const ToolRun bad = sampleLines(QOTA_DATA_DIR "/SainteHelens.dem",
                                  "5625\x01"
                                  "00 5114500\n");
  EXPECT_NE(bad.err.find("'5625\\x0100' is not a number"), std::string::npos) << bad.err;
}

TEST(TrustWork, AHugeRasterIsRefusedAtOnceWithItsEstimate) {
  // A VRT declaring 10^6 x 10^6 pixels over a small file: before, a pass over 10^12 heights
  // started with no estimate and no progress after minutes.
  const std::string vrt = scratchPath("trust/huge.vrt").string();
  std::ofstream(vrt) << "<VRTDataset rasterXSize=\"1000000\" rasterYSize=\"1000000\"><GeoTransform>500000, 30, 0, "
                        "5100000, 0, -30</GeoTransform><VRTRasterBand dataType=\"Float32\" band=\"1\"><SimpleSource>"
                        "<SourceFilename relativeToVRT=\"1\">sh.tif</SourceFilename><SourceBand>1</SourceBand>"
                        "<SrcRect xOff=\"0\" yOff=\"0\" xSize=\"50\" ySize=\"50\"/><DstRect xOff=\"0\" yOff=\"0\" "
                        "xSize=\"50\" ySize=\"50\"/></SimpleSource></VRTRasterBand></VRTDataset>\n";
  (void)helens();
  ShadowOptions o = at(vrt, "trust/huge.tif");
  o.pixelSize = 30;
  expectRefused(shadow(o),
                "more than --max-pixels 4294967296 allows: at the measured rates, reading its heights takes about",
                o.output);
  // --max-memory below a byte is no budget (it ran whole with the default before).
  EXPECT_THROW(qota::tools::parseByteSize("0.5"), qota::Error);
  EXPECT_THROW(qota::tools::parseByteSize("1e-300G"), qota::Error);
  // A budget below what the process itself takes is refused, naming what it takes.
  o = at(helens().dem, "trust/tiny_budget.tif");
  o.maxMemory = 16ull << 20;
  expectRefused(shadow(o), "the process itself takes", o.output);
}

}  // namespace
