// Shadows by tiles equal the whole raster's shadow (shadowMask and sunlightHours over
// localFrame, themselves held to brute force in test_shadow.cpp) pixel for pixel: several tile
// sizes, suns low and high from every side, voids and nodata across tile edges, on the ellipsoid,
// flat, projected (north up and rotated) and without CRS.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "qota/error.hpp"
#include "qota/instant.hpp"
#include "qota/shadow.hpp"
#include "qota/shadow_tiles.hpp"
#include "qota/sunlight.hpp"
#include "raster_files.hpp"
#include "shadow_oracle.hpp"

namespace {

using qota::Light;
using qota::PixelWindow;
namespace test = qota::test;

constexpr double kNodata = -9999;

// A part of the Rainier DEM (real relief: the summit and its valleys), with voids: a round one
// and a long thin one across where tiles meet, and scattered nodata pixels. In `crs` with the
// geotransform `gt` (the Rainier pixel's own when empty).
std::string rainierPart(const std::string& name, const std::string& crs, std::array<double, 6> gt = {}) {
  const test::RasterValues all = test::readRaster(QOTA_DATA_DIR "/mt_rainier_90m.tif");
  constexpr int w = 150, h = 130, c0 = 520, r0 = 560;
  test::RasterSpec s;
  s.width = w, s.height = h;
  s.crs = crs;
  if (gt == std::array<double, 6>{}) {
    gt = all.geotransform;
    gt[0] += c0 * gt[1], gt[3] += r0 * gt[5];
  }
  s.geotransform = gt;
  s.nodata = kNodata;
  std::vector<double> z(static_cast<std::size_t>(w) * h);
  for (int r = 0; r < h; ++r) {
    for (int c = 0; c < w; ++c) {
      double v = all.at(c0 + c, r0 + r);
      if (v < -1000) v = kNodata;                          // the DEM's own voids
      if (std::hypot(c - 64, r - 48) < 7) v = kNodata;     // round void on tile corners
      if (r == 75 && c > 20 && c < 140) v = kNodata;       // a thin one along a row
      if ((c * 7919 + r * 104729) % 97 == 0) v = kNodata;  // scattered pixels
      z[static_cast<std::size_t>(r) * w + c] = v;
    }
  }
  s.bands = {z};
  const auto path = test::scratchPath(name);
  test::writeRaster(path, s);
  return path.string();
}

// Every pixel of the whole raster's mask against the tiles', for several tile sizes.
void expectTilesEqualWhole(const std::string& path, const qota::FrameOptions& frameOptions,
                           const std::vector<std::pair<double, double>>& suns, const std::vector<int>& sides) {
  const qota::DemTerrain dem = qota::loadDem(path, {.lonLatAsCartesian = true});
  const qota::LocalFrame whole = qota::localFrame(dem, frameOptions);
  const qota::ShadowTiles tiles(path, {.lonLatAsCartesian = true}, frameOptions);
  ASSERT_EQ(tiles.frame().minHeight, whole.minHeight);
  ASSERT_EQ(tiles.frame().maxHeight, whole.maxHeight);
  ASSERT_EQ(tiles.frame().pixelSizeX, whole.pixelSizeX);
  ASSERT_EQ(tiles.frame().body.lowest, whole.body.lowest);
  for (const auto& [azimuth, altitude] : suns) {
    const Eigen::Vector3d light = whole.towardSun({azimuth, altitude});
    const std::vector<Light> expected = qota::shadowMask(whole, light);
    std::size_t lit = 0;
    for (Light l : expected) lit += l == Light::Lit;
    for (int side : sides) {
      std::size_t differ = 0;
      for (int row = 0; row < dem.height; row += side) {
        for (int col = 0; col < dem.width; col += side) {
          const PixelWindow tile{col, row, std::min(side, dem.width - col), std::min(side, dem.height - row)};
          const std::vector<Light> got = tiles.mask(tile, light);
          for (int r = 0; r < tile.height; ++r) {
            for (int c = 0; c < tile.width; ++c) {
              differ += got[static_cast<std::size_t>(r) * tile.width + c] !=
                        expected[static_cast<std::size_t>(row + r) * dem.width + col + c];
            }
          }
        }
      }
      EXPECT_EQ(differ, 0u) << path << ": sun " << azimuth << "/" << altitude << ", tiles of " << side;
    }
    // In a flat frame, pixels spread over the raster also against the brute-force oracle
    // (shadow_oracle.hpp: every triangle, no qota shadow code), through the tiles of the last size.
    // The oracle is asked with the sun turned by 1e-7 degrees either way (bruteForcePixelTurned:
    // at azimuth 90 its rays run exactly along the rows' edges and slip between the triangles of
    // 183 pixels of the raster without CRS), and a pixel is checked where both answers agree.
    if (!whole.body.ellipsoid) {
      const int side = sides.back();
      std::size_t checked = 0, sampled = 0;
      for (std::size_t i = 7; i < expected.size(); i += expected.size() / 97) {
        if (!whole.valid[i]) continue;
        ++sampled;
        const std::optional<Light> oracle = qota::test::bruteForcePixelTurned(whole, i, {azimuth, altitude});
        if (!oracle) continue;
        const int col = static_cast<int>(i % dem.width), row = static_cast<int>(i / dem.width);
        const PixelWindow tile{col / side * side, row / side * side, std::min(side, dem.width - col / side * side),
                               std::min(side, dem.height - row / side * side)};
        const std::vector<Light> got = tiles.mask(tile, light);
        EXPECT_EQ(got[static_cast<std::size_t>(row - tile.row) * tile.width + (col - tile.col)], *oracle)
            << path << ": sun " << azimuth << "/" << altitude << ", pixel " << col << ", " << row;
        ++checked;
      }
      EXPECT_GT(checked, 30u);
      EXPECT_GE(checked + 2, sampled);  // (a knife-edge pixel or two at most)
    }
    // Neither all lit nor all dark: the comparison means something.
    EXPECT_GT(lit, 0u);
    EXPECT_LT(lit, expected.size() * 99 / 100) << azimuth << "/" << altitude;
  }
}

const std::vector<std::pair<double, double>> kSuns = {{315, 6}, {100, 35}, {200, 75}, {0, 15}, {90, 4}, {247, 10}};

TEST(ShadowTiles, EqualTheWholeRasterOnTheEllipsoid) {
  const std::string path = rainierPart("tiles_geographic.tif", "EPSG:4326");
  expectTilesEqualWhole(path, {}, kSuns, {23, 64});
  expectTilesEqualWhole(path, {}, {{315, 6}, {135, 20}}, {9, 150});
}

// Suns at, just above and just below the horizon on the ellipsoid: their shadows reach past the
// tiles' tangent planes, but not past the body's curve (the ball bound in the header); a sun far
// enough below every tile's horizon needs no halo at all (the body shades every pixel).
TEST(ShadowTiles, LowSunsOnTheEllipsoid) {
  const std::string path = rainierPart("tiles_low.tif", "EPSG:4326");
  expectTilesEqualWhole(path, {}, {{270, 0.3}, {95, 0.6}}, {40});
  const qota::DemTerrain dem = qota::loadDem(path, {.lonLatAsCartesian = true});
  const qota::LocalFrame whole = qota::localFrame(dem, qota::FrameOptions{});
  const qota::ShadowTiles tiles(path, {.lonLatAsCartesian = true}, {});
  for (const qota::SunPosition sun : {qota::SunPosition{270, 0.0}, qota::SunPosition{280, -0.2},
                                      qota::SunPosition{45, -1.0}, qota::SunPosition{200, -6.0}}) {
    const Eigen::Vector3d light = whole.towardSun(sun);
    const std::vector<Light> expected = qota::shadowMask(whole, light);
    std::size_t differ = 0, lit = 0;
    for (int row = 0; row < dem.height; row += 50) {
      for (int col = 0; col < dem.width; col += 50) {
        const PixelWindow tile{col, row, std::min(50, dem.width - col), std::min(50, dem.height - row)};
        const std::vector<Light> got = tiles.mask(tile, light);
        for (int r = 0; r < tile.height; ++r) {
          for (int c = 0; c < tile.width; ++c) {
            const Light e = expected[static_cast<std::size_t>(row + r) * dem.width + col + c];
            differ += got[static_cast<std::size_t>(r) * tile.width + c] != e;
            lit += e == Light::Lit;
          }
        }
      }
    }
    EXPECT_EQ(differ, 0u) << "sun " << sun.azimuth << "/" << sun.altitude << " (" << lit << " pixels lit)";
  }
}

TEST(ShadowTiles, EqualTheWholeRasterFlat) {
  const std::string path = rainierPart("tiles_flat.tif", "EPSG:4326");
  expectTilesEqualWhole(path, {.flat = true}, kSuns, {23, 64});
}

TEST(ShadowTiles, EqualTheWholeRasterOnAProjectedGrid) {
  // The same heights on a UTM grid of 90 m, north up and turned by a few degrees.
  const std::string north = rainierPart("tiles_utm.tif", "EPSG:32610", {594000, 90, 0, 5190000, 0, -90});
  expectTilesEqualWhole(north, {.flat = true}, kSuns, {23, 64});
  expectTilesEqualWhole(north, {}, {{315, 6}, {100, 35}, {0, 15}}, {31});
  const std::string turned =
      rainierPart("tiles_utm_turned.tif", "EPSG:32610", {594000, 89.5, 9.4, 5190000, 9.4, -89.5});
  expectTilesEqualWhole(turned, {.flat = true}, kSuns, {23, 64});
}

TEST(ShadowTiles, EqualTheWholeRasterWithoutCrs) {
  const std::string path = rainierPart("tiles_nocrs.tif", "", {0, 1, 0, 0, 0, 1});
  expectTilesEqualWhole(path, {.pixelSize = 90}, {{315, 6}, {100, 35}, {90, 4}}, {23, 64});
}

TEST(ShadowTiles, SunlightHoursEqualTheWholeRasters) {
  const std::string path = rainierPart("tiles_hours.tif", "EPSG:4326");
  const qota::DemTerrain dem = qota::loadDem(path, {.lonLatAsCartesian = true});
  const qota::LocalFrame whole = qota::localFrame(dem, qota::FrameOptions{});
  const qota::ShadowTiles tiles(path, {.lonLatAsCartesian = true}, {});
  const qota::LocalSpan span = qota::localSpan("2024-06-21", "America/Los_Angeles", 6, 20);
  const double start = span.start.julianDayUT, end = span.end.julianDayUT;
  const qota::SunlightHours expected = qota::sunlightHours(whole, path, start, end, 1.5);
  EXPECT_GE(tiles.horizonSlack(), whole.horizonSlack());
  const auto lights = tiles.sunlightSteps(start, end, 1.5, tiles.horizonSlack());
  ASSERT_FALSE(lights.empty());
  for (int side : {40, 150}) {
    std::size_t differ = 0;
    for (int row = 0; row < dem.height; row += side) {
      for (int col = 0; col < dem.width; col += side) {
        const PixelWindow tile{col, row, std::min(side, dem.width - col), std::min(side, dem.height - row)};
        const qota::SunlightHours got = tiles.hours(tile, start, end, 1.5);
        EXPECT_EQ(got.steps, expected.steps);
        for (int r = 0; r < tile.height; ++r) {
          for (int c = 0; c < tile.width; ++c) {
            differ += got.hours[static_cast<std::size_t>(r) * tile.width + c] !=
                      expected.hours[static_cast<std::size_t>(row + r) * dem.width + col + c];
          }
        }
      }
    }
    EXPECT_EQ(differ, 0u) << "tiles of " << side;
  }
}

// Steps the tiles skip and the whole raster computes: on a raster 30 degrees of longitude wide
// at sunset the Sun sets two hours earlier over its east than over its west, so a tile's window
// (a smaller slack, sunCanLight) skips steps at which the whole raster still makes masks. The
// skipped steps must be night over the tile in those masks too (the Sun below every pixel's
// horizon by more than the dip: the body shades them), and the hours equal.
TEST(ShadowTiles, HoursAtSunsetSkipNoStepTheWholeRasterLights) {
  const int w = 60, h = 24;
  std::vector<double> z(static_cast<std::size_t>(w) * h);
  for (int r = 0; r < h; ++r) {
    for (int c = 0; c < w; ++c) {
      // Ridges across the sunset's light, up to 4 km, and a few voids.
      double v = 2000 + 2000 * std::sin(0.9 * c) * std::cos(0.7 * r);
      if ((c * 31 + r * 17) % 53 == 0) v = kNodata;
      z[static_cast<std::size_t>(r) * w + c] = v;
    }
  }
  test::RasterSpec s;
  s.width = w, s.height = h;
  s.crs = "EPSG:4326";
  s.geotransform = {-125.0, 0.5, 0, 42.0, 0, -0.5};
  s.nodata = kNodata;
  s.bands = {z};
  const auto path = test::scratchPath("tiles_sunset.tif").string();
  test::writeRaster(path, s);
  const qota::DemTerrain dem = qota::loadDem(path, {.lonLatAsCartesian = true});
  const qota::LocalFrame whole = qota::localFrame(dem, qota::FrameOptions{});
  const qota::ShadowTiles tiles(path, {.lonLatAsCartesian = true}, {});
  const qota::LocalSpan span = qota::localSpan("2024-03-20", "America/Chicago", 19.75, 23);
  const double start = span.start.julianDayUT, end = span.end.julianDayUT, step = 0.25;
  const qota::SunlightHours expected = qota::sunlightHours(whole, path, start, end, step);
  // The whole raster lights more steps than its east tiles' windows do, and some pixels get
  // hours, others none.
  std::size_t someHours = 0, none = 0;
  for (std::size_t i = 0; i < expected.hours.size(); ++i) {
    if (!whole.valid[i]) continue;
    (expected.hours[i] > 0 ? someHours : none) += 1;
  }
  EXPECT_GT(someHours, 100u);
  EXPECT_GT(none, 100u);
  std::size_t skippedSomewhere = 0;
  for (int side : {12, 20}) {
    std::size_t differ = 0;
    for (int row = 0; row < h; row += side) {
      for (int col = 0; col < w; col += side) {
        const PixelWindow tile{col, row, std::min(side, w - col), std::min(side, h - row)};
        const qota::SunlightHours got = tiles.hours(tile, start, end, step);
        EXPECT_EQ(got.steps, expected.steps);
        for (int r = 0; r < tile.height; ++r) {
          for (int c = 0; c < tile.width; ++c) {
            differ += got.hours[static_cast<std::size_t>(r) * tile.width + c] !=
                      expected.hours[static_cast<std::size_t>(row + r) * w + col + c];
          }
        }
        // Does this tile's own window skip a step the whole raster lights?
        for (const qota::SunlightStep& st : qota::sunlightSteps(start, end, step)) {
          const qota::SunPosition atWhole = qota::sunOverFrame(whole, st.middleJulianDay, path);
          const double lon = -125.0 + 0.5 * (col + tile.width / 2.0), lat = 42.0 - 0.5 * (row + tile.height / 2.0);
          const qota::SunPosition atTile = qota::sunPosition(st.middleJulianDay, lon, lat);
          skippedSomewhere += qota::sunCanLight(whole, atWhole, whole.horizonSlack()) && atTile.altitude < -3;
        }
      }
    }
    EXPECT_EQ(differ, 0u) << "tiles of " << side;
  }
  EXPECT_GT(skippedSomewhere, 0u);  // (the case the test is for)
}

// Heights given by blocks with their overlap (as Dask gives them) to tiles restored from a state
// in another object, as from another process: the whole raster's mask.
TEST(ShadowTiles, BlocksWithTheirOverlapFromARestoredState) {
  const std::string path = rainierPart("tiles_blocks.tif", "EPSG:4326");
  const qota::DemTerrain dem = qota::loadDem(path, {.lonLatAsCartesian = true});
  const qota::LocalFrame whole = qota::localFrame(dem, qota::FrameOptions{});
  const qota::ShadowTiles restored =
      qota::ShadowTiles::restore(qota::ShadowTiles(path, {.lonLatAsCartesian = true}, {}).state());
  EXPECT_EQ(restored.frame().body.lowest, whole.body.lowest);
  test::RasterValues raw = test::readRaster(path);
  for (double& v : raw.values) v = v == kNodata ? NAN : v;
  const auto heightsOf = [&](const PixelWindow& w) {
    std::vector<double> heights;
    for (int r = w.row; r < w.row + w.height; ++r) {
      for (int c = w.col; c < w.col + w.width; ++c) heights.push_back(raw.at(c, r));
    }
    return heights;
  };
  for (const auto& [azimuth, altitude] : std::vector<std::pair<double, double>>{{315, 6}, {100, 35}}) {
    const Eigen::Vector3d light = whole.towardSun({azimuth, altitude});
    const std::vector<Light> expected = qota::shadowMask(whole, light);
    constexpr int side = 48;
    const std::array<int, 4> halo = restored.haloFor(side, side, {light});
    const int overlap = *std::max_element(halo.begin(), halo.end()) + 40;  // and room for the voids' fill
    std::size_t differ = 0;
    for (int row = 0; row < dem.height; row += side) {
      for (int col = 0; col < dem.width; col += side) {
        const PixelWindow tile{col, row, std::min(side, dem.width - col), std::min(side, dem.height - row)};
        const PixelWindow block =
            restored.checkableWindow({std::max(0, col - overlap), std::max(0, row - overlap),
                                      std::min(dem.width, col + tile.width + overlap) - std::max(0, col - overlap),
                                      std::min(dem.height, row + tile.height + overlap) - std::max(0, row - overlap)});
        const std::vector<Light> got = restored.maskFromHeights(block, heightsOf(block), tile, light);
        for (int r = 0; r < tile.height; ++r) {
          for (int c = 0; c < tile.width; ++c) {
            differ += got[static_cast<std::size_t>(r) * tile.width + c] !=
                      expected[static_cast<std::size_t>(row + r) * dem.width + col + c];
          }
        }
      }
    }
    EXPECT_EQ(differ, 0u) << azimuth << "/" << altitude;
  }
  // Too little overlap is an error naming what the tile needs.
  const PixelWindow tile{70, 70, 20, 20};
  const PixelWindow around = restored.checkableWindow(tile);
  const auto refused = [&](const PixelWindow& window, const std::vector<double>& heights, const std::string& why) {
    try {
      (void)restored.maskFromHeights(window, heights, tile, whole.towardSun({315, 6}));
      ADD_FAILURE() << "no error: " << why;
    } catch (const qota::Error& e) {
      EXPECT_NE(std::string(e.what()).find(why), std::string::npos) << e.what();
    }
  };
  refused(around, heightsOf(around), "larger overlap");
  // Heights that are not the raster's (another raster on the same grid, one pixel changed), or a
  // window that is not whole hash blocks, are refused: they cannot be checked.
  std::vector<double> changed = heightsOf(around);
  changed[changed.size() / 2] += 0.5;
  refused(around, changed, "are not those the shadow tiles were made from");
  refused(around, std::vector<double>(around.pixelCount(), 1500.0), "are not those the shadow tiles were made from");
  refused(tile, heightsOf(tile), "not whole hash blocks");
  EXPECT_THROW(qota::ShadowTiles::restore("qota-shadow-tiles 1\npath 3 abc\nwidth zz\n"), qota::Error);
}

TEST(ShadowTiles, RefusesWhatCannotBeTiledExactly) {
  const std::string path = rainierPart("tiles_refused.tif", "EPSG:4326");
  const qota::ShadowTiles tiles(path, {.lonLatAsCartesian = true}, {});
  const PixelWindow tile{0, 0, 30, 30};
  // (A sun at or below the centre's horizon on the ellipsoid is tiled: LowSunsOnTheEllipsoid.)
  // A window over the memory allowed, naming both.
  try {
    (void)tiles.mask(tile, tiles.frame().towardSun({135, 3}), {}, 0, qota::ShadowSearch::Strips, 100000);
    ADD_FAILURE() << "no error";
  } catch (const qota::Error& e) {
    EXPECT_NE(std::string(e.what()).find("allowed"), std::string::npos) << e.what();
  }
  // Tiles that fit a budget: their worst window fits it, a larger side's does not.
  const std::vector<Eigen::Vector3d> lights{tiles.frame().towardSun({135, 60})};
  const std::uint64_t budget = 8000 * qota::ShadowTiles::bytesPerWindowPixel(lights);
  const int side = tiles.tileSideFor(budget, lights, 16);
  EXPECT_GE(side, 16);
  EXPECT_LT(side, 90);
  const PixelWindow centre{(150 - side) / 2, (130 - side) / 2, side, std::min(side, 130)};
  EXPECT_LE(tiles.windowOf(centre, tiles.halo(centre, lights, tiles.frame().minHeight)).pixelCount(), 8000u);
  EXPECT_EQ(tiles.tileSideFor(1000, lights, 16), 0);
}

// A raster of all voids but a corner, tiled: the fill reaches across the window to where the
// data is, the same as the whole raster's.
TEST(ShadowTiles, WideVoidsFillAsOverTheWholeRaster) {
  test::RasterSpec s;
  s.width = 120, s.height = 90;
  s.crs = "EPSG:32610";
  s.geotransform = {594000, 30, 0, 5190000, 0, -30};
  s.nodata = kNodata;
  std::vector<double> z(static_cast<std::size_t>(s.width) * s.height, kNodata);
  for (int r = 0; r < s.height; ++r) {
    for (int c = 0; c < s.width; ++c) {
      // High ground west, low ground south: the void between them is filled as a slope that
      // shades the low ground at a low sun from the north-west, which a fill from the low
      // ground alone would not.
      double v = kNodata;
      if (c < 30) v = 1500 + 20 * ((c * 13 + r * 7) % 11);
      if (r > 70) v = 100 + 5 * ((c * 13 + r * 7) % 11);
      if (c > 100 && r < 10) v = 600;
      z[static_cast<std::size_t>(r) * s.width + c] = v;
    }
  }
  s.bands = {z};
  const auto path = test::scratchPath("tiles_wide_void.tif").string();
  test::writeRaster(path, s);
  expectTilesEqualWhole(path, {.flat = true}, {{315, 6}, {0, 8}, {100, 35}, {200, 20}}, {16, 50});
}

}  // namespace
