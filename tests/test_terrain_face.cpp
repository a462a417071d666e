// qota::Terrain, the face users hold: points in the source's own coordinates (a UTM DEM's
// easting and northing, where the index's own calls take coordinates relative to the raster's
// centre), heights in its unit and reference, single and batched alike. Expected values are the
// rasters' own pixels read with GDAL.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "qota/dem.hpp"
#include "qota/error.hpp"
#include "qota/terrain.hpp"
#include "qota/terrain_face.hpp"
#include "raster_files.hpp"

namespace {

TEST(TerrainFace, AnswersInTheSourcesOwnCoordinates) {
  const char* path = QOTA_DATA_DIR "/SainteHelens.dem";
  const qota::test::RasterValues r = qota::test::readRaster(path);
  const qota::Terrain dem = qota::Terrain::open({.source = path});
  // The index loadDem builds works around the raster's centre: the map coordinates are no point
  // of its own (the face is what a newcomer reaches for).
  const qota::DemTerrain loaded = qota::loadDem(path);
  const qota::CartesianIndex index(loaded.mesh, loaded.mapping);
  EXPECT_FALSE(index.height(562500, 5114500).has_value());
  std::mt19937_64 rng(5);
  std::uniform_int_distribution<int> col(1, r.width - 2), row(1, r.height - 2);
  std::vector<double> xs, ys, want;
  for (int k = 0; k < 400; ++k) {
    const int c = col(rng), w = row(rng);
    if (r.at(c, w) < -30000) continue;  // (nodata)
    xs.push_back(r.geotransform[0] + (c + 0.5) * r.geotransform[1]);
    ys.push_back(r.geotransform[3] + (w + 0.5) * r.geotransform[5]);
    want.push_back(r.at(c, w));
  }
  std::vector<double> batch(xs.size());
  dem.heights(xs, ys, batch);
  for (std::size_t i = 0; i < xs.size(); ++i) {
    const std::optional<double> h = dem.height(xs[i], ys[i]);
    ASSERT_TRUE(h) << xs[i] << " " << ys[i];
    EXPECT_NEAR(*h, want[i], 1e-6);
    EXPECT_EQ(*h, batch[i]);
    // The surface is at and below itself.
    EXPECT_EQ(dem.below(xs[i], ys[i], *h), h);
    EXPECT_EQ(dem.above(xs[i], ys[i], *h), h);
  }
  EXPECT_FALSE(dem.height(0, 0).has_value());  // off the raster
  EXPECT_STREQ(dem.mapping(), "cartesian");
  EXPECT_TRUE(dem.normalsMetric());  // UTM metres and heights in metres
}

TEST(TerrainFace, SaysWhenItsNormalsAreNotMetric) {
  // A lon/lat raster in the cartesian mapping: x, y in degrees, heights in metres, so a normal
  // is a unit vector of that mixed frame; on the ellipsoid the frame is ECEF metres.
  qota::SourceOptions o;
  o.source = QOTA_DATA_DIR "/mt_rainier_90m.tif";
  EXPECT_FALSE(qota::Terrain::open(o).normalsMetric());
  o.mapping = "geodetic";
  EXPECT_TRUE(qota::Terrain::open(o).normalsMetric());
}

TEST(TerrainFace, LonLatOnTheEllipsoidOverItsGeoid) {
  // Rainier's pixels are heights over EGM96: at a pixel centre, the face answers the pixel (the
  // geoid's undulation put on and taken off), and a longitude one turn away answers alike.
  const char* path = QOTA_DATA_DIR "/mt_rainier_90m.tif";
  const qota::test::RasterValues r = qota::test::readRaster(path);
  qota::SourceOptions o;
  o.source = path;
  o.mapping = "geodetic";
  const qota::Terrain rainier = qota::Terrain::open(o);
  EXPECT_NE(rainier.heightRef().find("EGM96"), std::string::npos) << rainier.heightRef();
  const int c = 600, w = 600;
  const double x = r.geotransform[0] + (c + 0.5) * r.geotransform[1],
               y = r.geotransform[3] + (w + 0.5) * r.geotransform[5];
  ASSERT_TRUE(rainier.height(x, y));
  EXPECT_NEAR(*rainier.height(x, y), r.at(c, w), 1e-6);
  EXPECT_EQ(rainier.height(x + 360, y), rainier.height(x, y));
  const std::vector<qota::Hit> layers = rainier.all(x, y);
  ASSERT_FALSE(layers.empty());
  EXPECT_NEAR(layers[0].height, r.at(c, w), 1e-6);
}

TEST(TerrainFace, AMeshAnswersInItsOwnCoordinates) {
  // A block of Delft: a point whose only face is flat at z = 7.88 in the file.
  const qota::Terrain delft = qota::Terrain::open({.source = QOTA_DATA_DIR "/testarea.obj"});
  ASSERT_TRUE(delft.height(84900, 447600));
  EXPECT_NEAR(*delft.height(84900, 447600), 7.88, 1e-9);
}

}  // namespace
