// Terrains from real rasters through GDAL.
#include <gdal_priv.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <random>

#include "qota/dem.hpp"
#include "qota/error.hpp"
#include "qota/terrain.hpp"
#include "raster_files.hpp"

namespace {

using qota::CartesianIndex;
using qota::DemTerrain;

std::filesystem::path scratch(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() / "qota_tests";
  std::filesystem::create_directories(dir);
  return dir / name;
}

// Every pixel centre of the real tile gives back the raster value; nodata pixels have no terrain
// except where a neighbouring valid triangle reaches them (it cannot: every triangle touching a
// nodata vertex is gone), so they all miss.
TEST(Dem, RainierPixelCentresAreRasterValues) {
  const DemTerrain dem = qota::loadDem(QOTA_DATA_DIR "/mt_rainier_90m.tif", {.lonLatAsCartesian = true});
  ASSERT_EQ(dem.width, 1201);
  ASSERT_EQ(dem.height, 1201);
  ASSERT_TRUE(dem.nodata);
  EXPECT_EQ(*dem.nodata, -32768);
  EXPECT_EQ(dem.nodataPixels, 9033u);
  EXPECT_NE(dem.crsWkt.find("WGS 84"), std::string::npos);
  const CartesianIndex index(dem.mesh, dem.mapping);

  qota::ensureGdalRegistered();
  std::unique_ptr<GDALDataset> ds(GDALDataset::Open(QOTA_DATA_DIR "/mt_rainier_90m.tif", GDAL_OF_RASTER));
  std::vector<double> raster(1201 * 1201);
  ASSERT_EQ(ds->GetRasterBand(1)->RasterIO(GF_Read, 0, 0, 1201, 1201, raster.data(), 1201, 1201, GDT_Float64, 0, 0),
            CE_None);
  std::uint64_t checked = 0, isolated = 0;
  for (int r = 0; r < 1201; ++r) {
    for (int c = 0; c < 1201; ++c) {
      const auto xy = dem.pixelCentre(c, r);
      const Eigen::Vector3d m = dem.mapping.toMapped({xy[0], xy[1], 0});
      const auto hit = index.top(m.x(), m.y());
      const double value = raster[static_cast<std::size_t>(r) * 1201 + c];
      if (value == -32768) {
        ASSERT_FALSE(hit) << c << ' ' << r;
        continue;
      }
      if (!hit) {
        ++isolated;  // a valid pixel all of whose triangles touch nodata
        continue;
      }
      ASSERT_NEAR(hit->height, value, 1e-9) << c << ' ' << r;
      ++checked;
    }
  }
  EXPECT_GT(checked, 1201u * 1201u - 9033u - 2000u);
  EXPECT_LT(isolated, 2000u);
}

TEST(Dem, BetweenCentresIsTheContainingTriangle) {
  const DemTerrain dem = qota::loadDem(QOTA_DATA_DIR "/SainteHelens.dem");
  EXPECT_EQ(dem.driver, "USGSDEM");
  EXPECT_EQ(dem.width, 327);
  EXPECT_EQ(dem.height, 468);
  const CartesianIndex index(dem.mesh, dem.mapping);
  // Halfway between the centres of pixel (c, r) and (c + 1, r + 1): on the documented diagonal,
  // so the mean of the two diagonal corners.
  const auto z = [&](int c, int r) { return dem.mesh.vertices[static_cast<std::size_t>(r) * dem.width + c].z(); };
  for (int r = 10; r < 460; r += 37) {
    for (int c = 10; c < 320; c += 29) {
      const auto xy = dem.pixelCentre(c + 0.5, r + 0.5);
      const auto hit = index.topWorld({xy[0], xy[1], 0});
      ASSERT_TRUE(hit);
      EXPECT_NEAR(hit->height, 0.5 * (z(c, r) + z(c + 1, r + 1)), 1e-9);
      // A quarter of the way along the other diagonal lies in the (TL, BR, TR) triangle.
      const auto q = dem.pixelCentre(c + 0.75, r + 0.25);
      const double expect = z(c, r) + 0.75 * (z(c + 1, r + 1) - z(c, r + 1)) + 0.25 * (z(c, r + 1) - z(c, r));
      (void)expect;
      const auto h2 = index.topWorld({q[0], q[1], 0});
      ASSERT_TRUE(h2);
      // TL=(0,0), TR=(1,0), BR=(1,1) in (col, row): h = TL + col*(TR-TL) + row*(BR-TR).
      const double e2 = z(c, r) + 0.75 * (z(c + 1, r) - z(c, r)) + 0.25 * (z(c + 1, r + 1) - z(c + 1, r));
      EXPECT_NEAR(h2->height, e2, 1e-9);
    }
  }
}

// Writes a small raster with the given geotransform and values through GDAL.
void writeRaster(const std::filesystem::path& path, const char* driver, int w, int h, const double gt[6],
                 const std::vector<float>& values, std::optional<double> nodata = std::nullopt) {
  qota::ensureGdalRegistered();
  GDALDriver* drv = GetGDALDriverManager()->GetDriverByName(driver);
  ASSERT_NE(drv, nullptr);
  std::unique_ptr<GDALDataset> ds(drv->Create(path.c_str(), w, h, 1, GDT_Float32, nullptr));
  ASSERT_NE(ds, nullptr);
  ds->SetGeoTransform(const_cast<double*>(gt));
  if (nodata) ds->GetRasterBand(1)->SetNoDataValue(*nodata);
  ASSERT_EQ(
      ds->GetRasterBand(1)->RasterIO(GF_Write, 0, 0, w, h, const_cast<float*>(values.data()), w, h, GDT_Float32, 0, 0),
      CE_None);
}

TEST(Dem, RotatedGeotransform) {
  // A 30-degree rotated grid: pixel centres must still map to the raster values.
  const double a = M_PI / 6, s = 10.0;
  const double gt[6] = {1000, s * std::cos(a), -s * std::sin(a), 2000, s * std::sin(a), s * std::cos(a)};
  const int w = 20, h = 15;
  std::vector<float> values(w * h);
  for (int i = 0; i < w * h; ++i) values[i] = static_cast<float>((i * 37) % 101) * 0.5f;
  const auto path = scratch("rotated.tif");
  writeRaster(path, "GTiff", w, h, gt, values);
  const DemTerrain dem = qota::loadDem(path.string());
  const CartesianIndex index(dem.mesh, dem.mapping);
  for (int r = 0; r < h; ++r) {
    for (int c = 0; c < w; ++c) {
      const auto xy = dem.pixelCentre(c, r);
      EXPECT_NEAR(xy[0], 1000 + (c + 0.5) * gt[1] + (r + 0.5) * gt[2], 1e-9);
      const auto hit = index.topWorld({xy[0], xy[1], 0});
      ASSERT_TRUE(hit) << c << ' ' << r;
      EXPECT_NEAR(hit->height, values[r * w + c], 1e-9);
    }
  }
}

TEST(Dem, NodataMakesHoles) {
  const double gt[6] = {0, 1, 0, 10, 0, -1};
  std::vector<float> values(10 * 10, 5.0f);
  values[4 * 10 + 4] = -9999;  // one void pixel
  const auto path = scratch("holes.tif");
  writeRaster(path, "GTiff", 10, 10, gt, values, -9999.0);
  const DemTerrain dem = qota::loadDem(path.string());
  EXPECT_EQ(dem.nodataPixels, 1u);
  EXPECT_EQ(dem.mesh.polygonCount(), 2u * 81 - 6);  // the 6 triangles around the void vertex
  const CartesianIndex index(dem.mesh, dem.mapping);
  const auto centre = dem.pixelCentre(4, 4);
  EXPECT_FALSE(index.topWorld({centre[0], centre[1], 0}));
  const auto near = dem.pixelCentre(4.4, 4.1);
  EXPECT_FALSE(index.topWorld({near[0], near[1], 0}));
  const auto far = dem.pixelCentre(2.5, 2.5);
  EXPECT_EQ(index.topWorld({far[0], far[1], 0})->height, 5.0);
}

TEST(Dem, SrtmHgtAndOtherDrivers) {
  // The same tile as SRTM .hgt (the driver takes its georeferencing from the file name).
  qota::ensureGdalRegistered();
  std::unique_ptr<GDALDataset> src(GDALDataset::Open(QOTA_DATA_DIR "/mt_rainier_90m.tif", GDAL_OF_RASTER));
  const auto path = scratch("N46W122.hgt");
  GDALDriver* drv = GetGDALDriverManager()->GetDriverByName("SRTMHGT");
  ASSERT_NE(drv, nullptr);
  std::unique_ptr<GDALDataset> copy(drv->CreateCopy(path.c_str(), src.get(), FALSE, nullptr, nullptr, nullptr));
  ASSERT_NE(copy, nullptr);
  copy.reset();
  const DemTerrain hgt = qota::loadDem(path.string(), {.lonLatAsCartesian = true});
  EXPECT_EQ(hgt.driver, "SRTMHGT");
  const DemTerrain tif = qota::loadDem(QOTA_DATA_DIR "/mt_rainier_90m.tif", {.lonLatAsCartesian = true});
  EXPECT_EQ(hgt.mesh.polygonCount(), tif.mesh.polygonCount());
  const CartesianIndex a(hgt.mesh, hgt.mapping), b(tif.mesh, tif.mapping);
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> lon(-122, -121), lat(46, 47);
  for (int i = 0; i < 1000; ++i) {
    const Eigen::Vector3d p(lon(rng), lat(rng), 0);
    const auto ha = a.topWorld(p), hb = b.topWorld(p);
    ASSERT_EQ(ha.has_value(), hb.has_value());
    if (ha) {
      EXPECT_NEAR(ha->height, hb->height, 1e-6);
    }
  }
}

TEST(Dem, ErrorsNameTheFile) {
  try {
    qota::loadDem("/nonexistent/dir/none.tif");
    FAIL();
  } catch (const qota::Error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/dir/none.tif"), std::string::npos);
  }
  const auto text = scratch("not_a_raster.tif");
  { std::ofstream(text) << "hello\n"; }
  EXPECT_THROW(qota::loadDem(text.string()), qota::Error);
  EXPECT_THROW(qota::loadDem(QOTA_DATA_DIR "/mt_rainier_90m.tif", {2, 0}), qota::Error);
}

// Pixels 10^149 times taller than wide, or sheared nearly flat, are a broken geotransform: refused
// with its numbers, by every reader. A thousand to one (a cross-section raster) still loads.
TEST(Dem, PixelsFarLongerOneWayThanTheOtherAreRefused) {
  const std::vector<float> values(12 * 10, 5.0f);
  const auto path = scratch("pixel_shape.tif");
  const double slivers[6] = {0, 4.5e-72, 0, 0, 0, -2.3e77};
  writeRaster(path, "GTiff", 12, 10, slivers, values);
  for (const bool describeOnly : {false, true}) {
    try {
      describeOnly ? (void)qota::describeDem(path.string()) : (void)qota::loadDem(path.string());
      FAIL() << "loaded";
    } catch (const qota::Error& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("pixel_shape.tif"), std::string::npos) << what;
      EXPECT_NE(what.find("times as long one way as the other"), std::string::npos) << what;
    }
  }
  const double sheared[6] = {0, 10, 10, 0, 10, 10 + 1e-6};
  writeRaster(path, "GTiff", 12, 10, sheared, values);
  try {
    (void)qota::loadDem(path.string());
    FAIL() << "loaded";
  } catch (const qota::Error& e) {
    EXPECT_NE(std::string(e.what()).find("sheared to"), std::string::npos) << e.what();
  }
  const double crossSection[6] = {0, 1, 0, 0, 0, -1000};
  writeRaster(path, "GTiff", 12, 10, crossSection, values);
  const DemTerrain dem = qota::loadDem(path.string());
  EXPECT_EQ(dem.width, 12);
}

TEST(Dem, TooLargeForMemoryIsRefusedBeforeAllocating) {
  // A sparse 200000 x 200000 GeoTIFF: tiny on disk, about 15 TB as a terrain.
  qota::ensureGdalRegistered();
  const auto path = scratch("huge.tif");
  GDALDriver* drv = GetGDALDriverManager()->GetDriverByName("GTiff");
  char** co = nullptr;
  co = CSLSetNameValue(co, "SPARSE_OK", "TRUE");
  co = CSLSetNameValue(co, "TILED", "YES");
  co = CSLSetNameValue(co, "BIGTIFF", "YES");
  std::unique_ptr<GDALDataset> ds(drv->Create(path.c_str(), 200000, 200000, 1, GDT_Int16, co));
  CSLDestroy(co);
  ASSERT_NE(ds, nullptr);
  ds.reset();
  try {
    qota::loadDem(path.string());
    FAIL() << "expected a memory error";
  } catch (const qota::Error& e) {
    EXPECT_NE(std::string(e.what()).find("200000 x 200000"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("memory"), std::string::npos) << e.what();
  }
  // An explicit limit applies to small rasters too.
  EXPECT_THROW(qota::loadDem(QOTA_DATA_DIR "/SainteHelens.dem", {1, 1000000}), qota::Error);
}

}  // namespace

namespace {

std::string writeSmall(const std::string& name, const std::string& crs, const std::string& unit, int bands = 1) {
  qota::test::RasterSpec s;
  s.width = s.height = 4;
  s.geotransform = {500000, 30, 0, 5200000, 0, -30};
  s.crs = crs;
  s.unitType = unit;
  for (int b = 0; b < bands; ++b) s.bands.push_back(std::vector<double>(16, 100.0 + b));
  const auto path = qota::test::scratchPath(name);
  qota::test::writeRaster(path, s);
  return path.string();
}

TEST(Dem, LonLatIsNotACartesianTerrainUnlessAskedFor) {
  // x, y in degrees and z in metres make no metric frame: refused, with the ways out named.
  try {
    qota::loadDem(QOTA_DATA_DIR "/mt_rainier_90m.tif");
    FAIL() << "a lon/lat raster was taken as a Cartesian terrain";
  } catch (const qota::Error& e) {
    for (const char* part : {"longitude/latitude", "loadOnEllipsoid", "gdalwarp", "lonLatAsCartesian"}) {
      EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
    }
  }
  EXPECT_EQ(qota::loadDem(QOTA_DATA_DIR "/mt_rainier_90m.tif", {.lonLatAsCartesian = true}).width, 1201);
  EXPECT_EQ(qota::loadDem(QOTA_DATA_DIR "/SainteHelens.dem").width, 327);  // projected: metric
}

TEST(Dem, VerticalUnitsFromTheBandOrTheCrs) {
  struct Case {
    const char* crs;
    const char* unit;
    double metres;
    bool known;
  };
  for (const Case& c :
       {Case{"EPSG:32610", "", 1.0, false}, Case{"EPSG:32610", "m", 1.0, true}, Case{"EPSG:32610", "metre", 1.0, true},
        Case{"EPSG:32610", "ft", 0.3048, true}, Case{"EPSG:32610", "Foot", 0.3048, true},
        Case{"EPSG:32610", "US survey foot", 1200.0 / 3937.0, true},
        Case{"EPSG:32610+5703", "", 1.0, true},              // NAVD88 height, metres
        Case{"EPSG:32610+6360", "", 1200.0 / 3937.0, true},  // NAVD88 height (ftUS)
        Case{"EPSG:32610+8228", "", 0.3048, true}}) {        // NAVD88 height (ft)
    const qota::DemTerrain d = qota::describeDem(writeSmall("units.tif", c.crs, c.unit));
    EXPECT_NEAR(d.verticalUnit.metresPerUnit, c.metres, 1e-15) << c.crs << " '" << c.unit << "'";
    EXPECT_EQ(d.verticalUnit.known(), c.known) << c.crs << " '" << c.unit << "'";
    // The heights stay in the raster's own unit.
    EXPECT_EQ(qota::loadDem(writeSmall("units.tif", c.crs, c.unit)).mesh.vertices[5].z(), 100.0);
  }
  try {
    qota::loadDem(writeSmall("celsius.tif", "EPSG:32610", "degC"));
    FAIL() << "a temperature was taken for heights";
  } catch (const qota::Error& e) {
    EXPECT_NE(std::string(e.what()).find("'degC'"), std::string::npos) << e.what();
  }
}

TEST(Dem, SeveralBandsNeedAChoice) {
  const std::string path = writeSmall("bands.tif", "EPSG:32610", "", 3);
  try {
    qota::loadDem(path);
    FAIL() << "band 1 was taken without asking";
  } catch (const qota::Error& e) {
    EXPECT_NE(std::string(e.what()).find("has 3 bands"), std::string::npos) << e.what();
  }
  const qota::DemTerrain d = qota::loadDem(path, {.band = 3});
  EXPECT_EQ(d.band, 3);
  EXPECT_EQ(d.mesh.vertices[0].z(), 102.0);
}

}  // namespace
