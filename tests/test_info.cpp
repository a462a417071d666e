// qota info, called as a library function: a raster's facts against GDAL's own reading of it,
// nothing built unless --tree.
#include <gtest/gtest.h>

#include <cmath>
#include <nlohmann/json.hpp>
#include <sstream>

#include "qota_tools.hpp"
#include "raster_files.hpp"

namespace {

using nlohmann::json;
using qota::tools::InfoOptions;

const std::string kRainier = QOTA_DATA_DIR "/mt_rainier_90m.tif";

struct InfoRun {
  int code;
  std::string out, err;
};
InfoRun runInfo(const InfoOptions& o) {
  std::ostringstream out, err;
  const int code = qota::tools::info(o, out, err);
  return {code, out.str(), err.str()};
}
json infoJson(InfoOptions o) {
  o.json = true;
  const InfoRun r = runInfo(o);
  EXPECT_EQ(r.code, 0) << r.err;
  return json::parse(r.out);
}

// Each band's lowest and highest value and its valid pixels, read by GDAL, nodata left out and
// scale and offset applied: the reference for --stats.
struct GdalRange {
  double lo = INFINITY, hi = -INFINITY;
  std::uint64_t valid = 0;
};
GdalRange gdalRange(const std::string& path, int b) {
  std::unique_ptr<GDALDataset> ds(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER));
  GDALRasterBand* band = ds->GetRasterBand(b);
  int hasNodata = FALSE;
  const double nodata = band->GetNoDataValue(&hasNodata);
  const double scale = band->GetScale(), offset = band->GetOffset();
  const int w = band->GetXSize(), h = band->GetYSize();
  std::vector<double> v(static_cast<std::size_t>(w) * h);
  EXPECT_EQ(band->RasterIO(GF_Read, 0, 0, w, h, v.data(), w, h, GDT_Float64, 0, 0), CE_None);
  GdalRange r;
  for (double x : v) {
    if ((hasNodata && x == nodata) || !std::isfinite(x)) continue;
    ++r.valid;
    r.lo = std::min(r.lo, x * scale + offset), r.hi = std::max(r.hi, x * scale + offset);
  }
  return r;
}

TEST(InfoTool, DescribesARasterAsGdalReadsItWithoutBuilding) {
  InfoOptions o;
  o.source.source = kRainier;
  o.stats = true;
  const json j = infoJson(o);
  std::unique_ptr<GDALDataset> ds(GDALDataset::Open(kRainier.c_str(), GDAL_OF_RASTER));
  EXPECT_EQ(j["driver"], ds->GetDriver()->GetDescription());
  EXPECT_EQ(j["size"], json::array({ds->GetRasterXSize(), ds->GetRasterYSize()}));
  EXPECT_EQ(j["bands"], ds->GetRasterCount());
  double gt[6];
  ds->GetGeoTransform(gt);
  for (int i = 0; i < 6; ++i) EXPECT_EQ(j["geotransform"][i].get<double>(), gt[i]);
  EXPECT_EQ(j["band_1"]["type"], "Int16");
  EXPECT_EQ(j["band_1"]["nodata"].get<double>(), ds->GetRasterBand(1)->GetNoDataValue());
  const GdalRange r = gdalRange(kRainier, 1);
  EXPECT_EQ(j["band_1"]["min"].get<double>(), r.lo);
  EXPECT_EQ(j["band_1"]["max"].get<double>(), r.hi);
  EXPECT_EQ(j["band_1"]["valid_pixels"].get<std::uint64_t>(), r.valid);
  EXPECT_EQ(j["band_1"]["valid_pixels"].get<std::uint64_t>() + j["band_1"]["void_pixels"].get<std::uint64_t>(),
            1201u * 1201u);
  EXPECT_EQ(j["crs"], "WGS 84 (EPSG:4326)");
  EXPECT_EQ(j["heights_over"]["name"], "EGM96 geoid");
  EXPECT_TRUE(j["heights_over"]["assumed"].get<bool>());
  // Nothing built: no tree statistics.
  EXPECT_FALSE(j.contains("nodes"));
  EXPECT_EQ(j["grid_triangles"].get<std::uint64_t>(), 2u * 1200u * 1200u);
  // A 3 arc-second pixel at the tile's centre, 46.5 N: a 1200th of a degree, whose length on
  // WGS84 the published series give (of longitude 111412.84 cos p - 93.5 cos 3p + 0.118 cos 5p,
  // of latitude 111132.92 - 559.82 cos 2p + 1.175 cos 4p metres).
  const double p = 46.5 * M_PI / 180;
  const double lonDegree = 111412.84 * std::cos(p) - 93.5 * std::cos(3 * p) + 0.118 * std::cos(5 * p);
  const double latDegree = 111132.92 - 559.82 * std::cos(2 * p) + 1.175 * std::cos(4 * p);
  EXPECT_NEAR(j["pixel_size_on_the_ground_m"][0].get<double>(), lonDegree / 1200, 0.01);
  EXPECT_NEAR(j["pixel_size_on_the_ground_m"][1].get<double>(), latDegree / 1200, 0.01);
}

TEST(InfoTool, BandsUnitsScaleOffsetAndProjectedGround) {
  // A UTM raster of 30 m pixels on the central meridian near the equator: on the ground a pixel
  // is 30 / 0.9996 m east-west (the projection's scale factor there), in feet with a scale and
  // offset on the first band and a second band of another type.
  const auto path = qota::test::scratchPath("info_bands.tif");
  qota::test::RasterSpec s;
  s.width = 4, s.height = 3;
  // Easting 500000 is the central meridian of zone 31 (3 E).
  s.geotransform = {500000 - 60, 30, 0, 1000 + 45, 0, -30};
  s.crs = "EPSG:32631";
  s.bands = {{1, 2, 3, 4, 5, 6, 7, -9999, 9, 10, 11, 12}, {0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1}};
  s.nodata = -9999;
  s.unitType = "ft";
  s.type = GDT_Float32;
  qota::test::writeRaster(path, s);
  {
    std::unique_ptr<GDALDataset> ds(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER | GDAL_OF_UPDATE));
    ds->GetRasterBand(1)->SetScale(0.5);
    ds->GetRasterBand(1)->SetOffset(100);
  }
  InfoOptions o;
  o.source.source = path.string();
  o.stats = true;
  const json j = infoJson(o);
  EXPECT_EQ(j["bands"], 2);
  EXPECT_EQ(j["band_1"]["unit"], "ft");
  EXPECT_EQ(j["band_1"]["scale"].get<double>(), 0.5);
  EXPECT_EQ(j["band_1"]["offset"].get<double>(), 100.0);
  const GdalRange r = gdalRange(path.string(), 1);
  EXPECT_EQ(j["band_1"]["min"].get<double>(), r.lo);  // 100.5
  EXPECT_EQ(j["band_1"]["max"].get<double>(), r.hi);  // 106
  EXPECT_EQ(r.lo, 100.5);
  EXPECT_EQ(j["band_1"]["void_pixels"], 1);
  EXPECT_EQ(j["band_2"]["max"].get<double>(), 1.0);
  EXPECT_EQ(j["metres_per_unit"].get<double>(), 0.3048);
  EXPECT_EQ(j["crs_kind"], "projected");
  EXPECT_NEAR(j["pixel_size_on_the_ground_m"][0].get<double>(), 30 / 0.9996, 0.002);
  EXPECT_NEAR(j["pixel_size_on_the_ground_m"][1].get<double>(), 30 / 0.9996, 0.002);
  // The extent in longitude/latitude: 60 m either side of 3 E, on the equator's north side.
  EXPECT_NEAR(j["extent_lon_lat"][0].get<double>(), 3 - 60 / 0.9996 / 111319.5, 1e-6);
  EXPECT_NEAR(j["extent_lon_lat"][2].get<double>(), 3 + 60 / 0.9996 / 111319.5, 1e-6);
  // The text form says the same, one fact a line.
  o.json = false;
  const InfoRun text = runInfo(o);
  EXPECT_NE(text.out.find("band 1: Float32, unit ft, nodata -9999, scale 0.5, offset 100, heights 100.5 to 106"),
            std::string::npos)
      << text.out;
  EXPECT_NE(text.out.find("vertical unit: ft (0.3048 m)"), std::string::npos) << text.out;
}

TEST(InfoTool, TreeBuildsAndPrintsTable4Statistics) {
  InfoOptions o;
  o.source.source = QOTA_DATA_DIR "/SainteHelens.dem";
  o.source.index.tree.maxPoly = 12;
  o.tree = true;
  const InfoRun r = runInfo(o);
  ASSERT_EQ(r.code, 0) << r.err;
  for (const char* key :
       {"size: 327 x 468", "triangles: 296197", "nodes: ", "memory (MB): ", "average tests per query: ", "depth: ",
        "leaves: ", "max poly: 12", "max polygons per leaf: ", "leaf references: ", "crs: "}) {
    EXPECT_NE(r.out.find(key), std::string::npos) << key << "\n" << r.out;
  }
  o.json = true;
  const json j = json::parse(runInfo(o).out);
  EXPECT_EQ(j["triangles"], 296197);
  EXPECT_GT(j["nodes"].get<int>(), 1);
  o.source.source = "/no/such.dem";
  EXPECT_EQ(runInfo(o).code, 2);
}

TEST(InfoTool, AHugeRasterIsDescribedAndItsTreeRefusedWithTheStreamingTools) {
  // 24020 x 24020 pixels as a VRT (the tile, and nodata around it): described at once; its tree
  // would take hundreds of GiB, refused before anything large is allocated.
  const auto path = qota::test::scratchPath("info_huge.vrt");
  {
    GDALAllRegister();  // (this test may run alone, before anything of qota's has opened a raster)
    std::unique_ptr<GDALDataset> in(GDALDataset::Open(kRainier.c_str(), GDAL_OF_RASTER));
    const char* args[] = {"-of", "VRT", "-srcwin", "0", "0", "24020", "24020", nullptr};
    GDALTranslateOptions* t = GDALTranslateOptionsNew(const_cast<char**>(args), nullptr);
    GDALClose(GDALTranslate(path.c_str(), GDALDataset::ToHandle(in.get()), t, nullptr));
    GDALTranslateOptionsFree(t);
  }
  InfoOptions o;
  o.source.source = path.string();
  const json j = infoJson(o);
  EXPECT_EQ(j["size"], json::array({24020, 24020}));
  EXPECT_GT(j["memory_tree_bytes"].get<double>(), 100e9);
  o.tree = true;
  const InfoRun r = runInfo(o);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("qota sample streams it"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("without building"), std::string::npos) << r.err;
}

}  // namespace
