// Shadow masks: exact cases, the brute-force oracle, a ray march on the real DEM, the tool.
#include <GeographicLib/Geodesic.hpp>
#include <gdal_priv.h>
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cstring>
#include <filesystem>
#include <random>
#include <sstream>

#include "qota/error.hpp"
#include "qota/shadow.hpp"
#include "qota/synthetic.hpp"
#include "qota/terrain.hpp"
#include "qota_tools.hpp"
#include "raster_files.hpp"
#include "shadow_oracle.hpp"
#include "shadow_strips.hpp"

namespace {

using qota::Light;
using qota::LocalFrame;

// A DEM in memory (no file): values row-major, pixel grid frame of `pixel` metres (no CRS).
qota::DemTerrain gridDem(int w, int h, const std::vector<double>& z) {
  qota::DemTerrain dem;
  dem.path = "grid";
  dem.width = w;
  dem.height = h;
  dem.geotransform = {0, 1, 0, 0, 0, -1};
  dem.mesh.vertices.resize(z.size());
  for (int r = 0; r < h; ++r) {
    for (int c = 0; c < w; ++c) dem.mesh.vertices[r * w + c] = {c + 0.5, -(r + 0.5), z[r * w + c]};
  }
  for (int r = 0; r + 1 < h; ++r) {
    for (int c = 0; c + 1 < w; ++c) {
      const auto tl = static_cast<std::uint32_t>(r * w + c), tr = tl + 1, bl = tl + w, br = bl + 1;
      if (std::isfinite(z[tl]) && std::isfinite(z[bl]) && std::isfinite(z[br])) dem.mesh.addTriangle(tl, bl, br);
      if (std::isfinite(z[tl]) && std::isfinite(z[br]) && std::isfinite(z[tr])) dem.mesh.addTriangle(tl, br, tr);
    }
  }
  return dem;
}

std::size_t count(const std::vector<Light>& m, Light l) { return std::count(m.begin(), m.end(), l); }

TEST(Shadow, FlatTerrainHasNoShadow) {
  const LocalFrame f = qota::localFrame(gridDem(40, 30, std::vector<double>(1200, 100.0)), false, 10);
  for (double alt : {0.5, 5.0, 30.0, 89.0}) {
    for (double az : {0.0, 45.0, 200.0, 333.3}) {
      const auto m = qota::shadowMask(f, f.towardSun({az, alt}));
      EXPECT_EQ(count(m, Light::Lit), 1200u) << az << ' ' << alt;
    }
  }
}

TEST(Shadow, StepCastsHOverTanAltitude) {
  // A 50 m step: the plateau (columns < 100) ends at column 99, the plain starts at column 100.
  // Sun from the west: a plain pixel at distance d = (col - 99) * 10 m from the plateau's edge is
  // in shadow exactly when 50 > d tan(alt).
  const int w = 200, h = 12;
  std::vector<double> z(w * h);
  for (int r = 0; r < h; ++r) {
    for (int c = 0; c < w; ++c) z[r * w + c] = c < 100 ? 50.0 : 0.0;
  }
  const LocalFrame f = qota::localFrame(gridDem(w, h, z), false, 10);
  for (double alt : {5.0, 10.0, 30.0, 45.0, 60.0, 80.0}) {
    const auto m = qota::shadowMask(f, f.towardSun({270, alt}));
    // Rows 0 and h - 1 are left out: there the ray runs exactly along the raster's outer edge,
    // which only one triangle touches, and rounding decides whether it grazes it.
    for (int r = 1; r + 1 < h; ++r) {
      for (int c = 0; c < w; ++c) {
        const bool expectShadow = c >= 100 && 50.0 > (c - 99) * 10.0 * std::tan(alt * M_PI / 180);
        ASSERT_EQ(m[r * w + c] == Light::Shadow, expectShadow) << "alt " << alt << " col " << c;
      }
    }
    // Its length is H / tan(alt) to within a pixel.
    const double length = 50.0 / std::tan(alt * M_PI / 180);
    int shadowed = 0;
    for (int c = 100; c < w; ++c) shadowed += m[5 * w + c] == Light::Shadow;
    EXPECT_NEAR(shadowed * 10.0, length, 10.0);
  }
}

TEST(Shadow, ZenithAndNight) {
  const qota::Heightfield hf = qota::fractalHeightfield(60, 50, 1.0, 30.0, 4);
  const LocalFrame f = qota::localFrame(gridDem(60, 50, hf.z), false, 10);
  EXPECT_EQ(count(qota::shadowMask(f, {0, 0, 1}), Light::Lit), 3000u);
  EXPECT_EQ(count(qota::shadowMask(f, f.towardSun({120, -3})), Light::Shadow), 3000u);
  EXPECT_EQ(count(qota::shadowMask(f, f.towardSun({120, 0})), Light::Shadow), 3000u);
  EXPECT_THROW(qota::shadowMask(f, {0, 0, 0}), qota::Error);
}

using qota::test::bruteForceMask;

TEST(Shadow, IdenticalToBruteForceOnSmallDems) {
  std::mt19937_64 rng(2024);
  std::uniform_real_distribution<double> az(0, 360), alt(2, 70);
  for (int k = 0; k < 12; ++k) {
    qota::Heightfield hf = qota::fractalHeightfield(28, 24, 1.0, 60.0 + 20 * k, 100 + k);
    if (k % 3 == 0) hf.z[5 * 28 + 7] = NAN;  // a void
    const LocalFrame f = qota::localFrame(gridDem(28, 24, hf.z), false, 10);
    const Eigen::Vector3d light = f.towardSun({az(rng), alt(rng)});
    const auto fast = qota::shadowMask(f, light, {{k % 2 ? 3u : 8u, 16}});
    const auto slow = bruteForceMask(f, light);
    for (std::size_t i = 0; i < fast.size(); ++i) {
      ASSERT_EQ(fast[i], slow[i]) << "case " << k << " pixel " << i << " (col " << i % 28 << ", row " << i / 28
                                  << ") light " << light.transpose();
    }
    EXPECT_GT(count(fast, Light::Shadow), 0u);
  }
}

// Suns along the grid's axes and its pixels' diagonals send rays exactly along shared edges and
// through vertices: every pixel against the oracle turned a hair either way (where the two agree).
TEST(Shadow, AxisAndDiagonalSunsAgreeWithTheOracle) {
  std::size_t checked = 0, knifeEdges = 0;
  int k = 0;
  for (const double azimuth : {0.0, 90.0, 180.0, 270.0, 45.0, 135.0, 225.0, 315.0}) {
    for (const double altitude : {3.0, 20.0}) {
      qota::Heightfield hf = qota::fractalHeightfield(26, 22, 1.0, 90.0 + 15 * k, 700 + k);
      if (k % 3 == 0) hf.z[7 * 26 + 9] = NAN;
      ++k;
      // Square pixels, so that the diagonal suns run along the cells' diagonals.
      const LocalFrame f = qota::localFrame(gridDem(26, 22, hf.z), false, 10);
      const auto fast = qota::shadowMask(f, f.towardSun({azimuth, altitude}));
      for (std::size_t i = 0; i < fast.size(); ++i) {
        if (!f.valid[i]) continue;
        const std::optional<Light> oracle = qota::test::bruteForcePixelTurned(f, i, {azimuth, altitude});
        if (!oracle) {
          ++knifeEdges;
          continue;
        }
        ++checked;
        ASSERT_EQ(fast[i], *oracle) << "sun " << azimuth << "/" << altitude << " pixel " << i << " (col " << i % 26
                                    << ", row " << i / 26 << ")";
      }
    }
  }
  EXPECT_GT(checked, 8000u);
  EXPECT_LT(knifeEdges, checked / 100);
}

// The strip walk (the default) against the light-frame quadtree, on every pixel: random suns,
// suns along the grid's axes and diagonals (strips parallel to rows, columns or pixel diagonals),
// grazing and steep suns, voids, and a frame whose triangles are found through the vertex table
// instead of the grid's arithmetic.
TEST(Shadow, StripWalkIdenticalToQuadtree) {
  std::mt19937_64 rng(77);
  std::uniform_real_distribution<double> az(0, 360), alt(1, 80);
  std::vector<qota::SunPosition> suns = {{0, 10},   {90, 10},   {180, 25}, {270, 3},    {45, 15},
                                         {135, 30}, {225, 0.5}, {315, 60}, {137.3, 10}, {10, 89}};
  for (int k = 0; k < 10; ++k) suns.push_back({az(rng), alt(rng)});
  std::size_t shadowed = 0, pixels = 0;
  for (int k = 0; k < static_cast<int>(suns.size()); ++k) {
    qota::Heightfield hf = qota::fractalHeightfield(41, 37, 1.0, 80.0 + 10 * k, 300 + k);
    if (k % 4 == 1) hf.z[9 * 41 + 11] = hf.z[9 * 41 + 12] = NAN;
    LocalFrame f = qota::localFrame(gridDem(41, 37, hf.z), false, 10);
    if (k % 5 == 2) f.gridMesh = false;
    const Eigen::Vector3d light = f.towardSun(suns[k]);
    const auto walk = qota::shadowMask(f, light, {}, {}, 1 + k % 3, qota::ShadowSearch::Strips);
    const auto tree = qota::shadowMask(f, light, {}, {}, 1, qota::ShadowSearch::Quadtree);
    ASSERT_EQ(walk.size(), tree.size());
    for (std::size_t i = 0; i < walk.size(); ++i) {
      ASSERT_EQ(walk[i], tree[i]) << "sun " << suns[k].azimuth << "/" << suns[k].altitude << " pixel " << i;
    }
    shadowed += count(walk, Light::Shadow);
    pixels += walk.size();
  }
  EXPECT_GT(shadowed, pixels / 10);
  EXPECT_LT(shadowed, pixels);
}

// Pixels a thousand times taller than wide, the sun across their tall side: every occluder spans
// a thousand pixel-wide strips, and went into each (19 million entries here, and gigabytes on
// larger rasters with absurd geotransforms). The strips widen instead, within a bounded number
// of copies, and the mask is still the quadtree's.
TEST(Shadow, StripsOfPixelsFarTallerThanWideStayBoundedAndExact) {
  const qota::Heightfield hf = qota::fractalHeightfield(300, 60, 1.0, 3000.0, 404);
  LocalFrame f = qota::localFrame(gridDem(300, 60, hf.z), false, 10);
  for (Eigen::Vector3d& v : f.mesh.vertices) v.y() *= 1000;
  f.pixelSizeY *= 1000;
  const Eigen::Vector3d light = f.towardSun({90, 20});
  std::vector<std::uint8_t> facing;
  const qota::shadow::HorizonStrips strips(f, light, std::min(f.pixelSizeX, f.pixelSizeY), facing, 2, 0);
  EXPECT_LT(strips.entryCount(), 4 * f.mesh.polygonCount() + 200000) << strips.stripCount() << " strips";
  const auto walk = qota::shadowMask(f, light, {}, {}, 2, qota::ShadowSearch::Strips);
  const auto tree = qota::shadowMask(f, light, {}, {}, 2, qota::ShadowSearch::Quadtree);
  ASSERT_EQ(walk.size(), tree.size());
  for (std::size_t i = 0; i < walk.size(); ++i) ASSERT_EQ(walk[i], tree[i]) << "pixel " << i;
  EXPECT_GT(count(walk, Light::Shadow), walk.size() / 10);
  EXPECT_GT(count(walk, Light::Lit), walk.size() / 20);
}

TEST(Shadow, StripWalkIdenticalToQuadtreeOnTheEllipsoid) {
  // The real DEM on WGS84: the rows and columns curve in the frame, the strips do not care.
  const qota::DemTerrain dem = qota::loadDem(QOTA_DATA_DIR "/mt_rainier_90m.tif", {.lonLatAsCartesian = true});
  const LocalFrame f = qota::localFrame(dem, false);
  for (const qota::SunPosition sun : {qota::SunPosition{137.3, 8}, qota::SunPosition{290, 25}}) {
    const Eigen::Vector3d light = f.towardSun(sun);
    const auto walk = qota::shadowMask(f, light);
    const auto tree = qota::shadowMask(f, light, {}, {}, 0, qota::ShadowSearch::Quadtree);
    std::size_t differ = 0;
    for (std::size_t i = 0; i < walk.size(); ++i) differ += walk[i] != tree[i];
    EXPECT_EQ(differ, 0u) << sun.azimuth << "/" << sun.altitude;
    EXPECT_GT(count(walk, Light::Shadow), walk.size() / 20);
  }
}

// The strips decide their candidates with mappedTriangleAbove, from the corners; the quadtree
// with its records. Every triangle's answer, or'ed, against the index's on points everywhere and
// on its corners and edges (where only the exact predicates agree), at heights on the surface and
// a rounding either side of it.
TEST(Shadow, MappedTriangleTestIsTheIndexs) {
  std::mt19937_64 rng(5);
  const qota::Heightfield hf = qota::fractalHeightfield(13, 11, 1.0, 40.0, 9);
  const LocalFrame f = qota::localFrame(gridDem(13, 11, hf.z), false, 10);
  std::uniform_real_distribution<double> az(0, 360), alt(3, 80), unit(0, 1);
  for (int sun = 0; sun < 4; ++sun) {
    const Eigen::Vector3d light = f.towardSun({az(rng), alt(rng)});
    const qota::CartesianMapping mapping(-light);
    const qota::CartesianIndex index(f.mesh, mapping);
    std::vector<Eigen::Vector3d> m(f.mesh.vertices.size());
    for (std::size_t i = 0; i < m.size(); ++i) m[i] = mapping.toMapped(f.mesh.vertices[i]);
    const auto anyTriangle = [&](double u, double v, double h, std::uint32_t vertex) {
      for (std::size_t t = 0; t < f.mesh.polygonCount(); ++t) {
        const auto c = f.mesh.polygon(t);
        if (c[0] == vertex || c[1] == vertex || c[2] == vertex) continue;
        if (qota::mappedTriangleAbove(m[c[0]], m[c[1]], m[c[2]], u, v, h)) return true;
      }
      return false;
    };
    std::size_t above = 0, checked = 0;
    const auto check = [&](double u, double v, double h, std::uint32_t vertex) {
      for (const double hh : {h, std::nextafter(h, -INFINITY), std::nextafter(h, INFINITY), h - 1, h + 1}) {
        const bool fast = index.occludedAbove(u, v, hh, vertex);
        ASSERT_EQ(fast, anyTriangle(u, v, hh, vertex)) << "sun " << sun << " at " << u << " " << v << " " << hh;
        above += fast;
        ++checked;
      }
    };
    for (std::uint32_t i = 0; i < m.size(); ++i) check(m[i].x(), m[i].y(), m[i].z(), i);
    for (std::size_t t = 0; t < f.mesh.polygonCount(); ++t) {
      const auto c = f.mesh.polygon(t);
      for (int k = 0; k < 3; ++k) {
        const Eigen::Vector3d mid = 0.5 * (m[c[k]] + m[c[(k + 1) % 3]]);
        check(mid.x(), mid.y(), mid.z(), 0xffffffffu);
      }
    }
    for (int k = 0; k < 300; ++k) {
      const Eigen::Vector3d& a = m[static_cast<std::size_t>(unit(rng) * (m.size() - 1))];
      check(a.x() + 20 * (unit(rng) - 0.5), a.y() + 20 * (unit(rng) - 0.5), a.z() + 30 * (unit(rng) - 0.5),
            0xffffffffu);
    }
    EXPECT_GT(above, checked / 20);
    EXPECT_LT(above, checked);
  }
}

// The naive baseline: from each pixel, step toward the sun half a pixel at a time until the ray
// leaves the grid; shadowed when the terrain (the same triangles, voids filled) rises above it.
std::vector<Light> rayMarch(const LocalFrame& f, const qota::SunPosition& sun, int rowStep) {
  const int w = f.width, h = f.height;
  const auto& v = f.mesh.vertices;
  const double sx = f.pixelSizeX, sy = f.pixelSizeY;
  const Eigen::Vector3d d = f.towardSun(sun);
  // Along the unit vector d by a length L: columns L dcol, rows L drow, height L d.z.
  const double dcol = d.x() / sx, drow = -d.y() / sy;
  const double step = 0.5 / std::max(std::fabs(dcol), std::fabs(drow));  // half a pixel
  auto heightAt = [&](double c, double r, double& z) {
    if (c < 0 || r < 0 || c > w - 1 || r > h - 1) return false;
    const int c0 = std::min(static_cast<int>(c), w - 2), r0 = std::min(static_cast<int>(r), h - 2);
    const double fc = c - c0, fr = r - r0;
    const auto Z = [&](int cc, int rr) { return v[static_cast<std::size_t>(rr) * w + cc].z(); };
    // Diagonal from (c0, r0) to (c0 + 1, r0 + 1): lower-left triangle when fr > fc.
    z = fr > fc ? Z(c0, r0) + fr * (Z(c0, r0 + 1) - Z(c0, r0)) + fc * (Z(c0 + 1, r0 + 1) - Z(c0, r0 + 1))
                : Z(c0, r0) + fc * (Z(c0 + 1, r0) - Z(c0, r0)) + fr * (Z(c0 + 1, r0 + 1) - Z(c0 + 1, r0));
    return true;
  };
  std::vector<Light> out(f.pixelCount(), Light::NoData);
  for (int r = 0; r < h; r += rowStep) {
    for (int c = 0; c < w; ++c) {
      const std::size_t i = static_cast<std::size_t>(r) * w + c;
      if (!f.valid[i]) continue;
      out[i] = Light::Lit;
      for (int k = 1;; ++k) {
        const double len = k * step;
        double z = 0;
        if (!heightAt(c + dcol * len, r + drow * len, z)) break;
        if (!std::isfinite(z)) continue;
        if (z > v[i].z() + d.z() * len) {
          out[i] = Light::Shadow;
          break;
        }
      }
    }
  }
  return out;
}

TEST(Shadow, AgreesWithRayMarchOnTheRealDem) {
  // The flat frame, where a ray march in pixel space is exact in its geometry; it samples the
  // terrain every half pixel, so it misses ridges thinner than that (and grazing rays), which
  // are the disagreements.
  const qota::DemTerrain dem = qota::loadDem(QOTA_DATA_DIR "/mt_rainier_90m.tif", {.lonLatAsCartesian = true});
  const LocalFrame f = qota::localFrame(dem, true);
  for (const qota::SunPosition sun : {qota::SunPosition{135, 20}, qota::SunPosition{250, 35}}) {
    const auto exact = qota::shadowMask(f, f.towardSun(sun));
    const auto march = rayMarch(f, sun, 7);
    std::size_t compared = 0, differ = 0, marchMissed = 0;
    for (std::size_t i = 0; i < exact.size(); ++i) {
      if (march[i] == Light::NoData) continue;
      ++compared;
      if (march[i] != exact[i]) {
        ++differ;
        marchMissed += exact[i] == Light::Shadow;
      }
    }
    RecordProperty("compared", static_cast<int>(compared));
    std::printf(
        "sun %g/%g: %zu pixels compared, %zu differ (%.4f %%), %zu of them shadows the "
        "march missed\n",
        sun.azimuth, sun.altitude, compared, differ, 100.0 * differ / compared, marchMissed);
    EXPECT_GT(compared, 200000u);
    EXPECT_LE(differ * 1000, compared);  // at least 99.9 % agree
  }
}

// A flat frame's points placed on demand (FlatPlacement: a viewshed's sweep keeps no vertex
// array) are the frame's vertices bit for bit: on a pixel grid, degrees scaled flat and a
// projected grid, over the whole raster and a window of it. A frame on an ellipsoid has no such
// placement.
TEST(Frame, FlatPlacementIsTheFramesVertices) {
  const auto expectSame = [](const qota::DemTerrain& dem, const qota::FrameOptions& options) {
    qota::FrameBasis basis;
    const LocalFrame whole = qota::localFrame(dem, options, basis);
    const qota::FlatPlacement flat(basis);
    const auto bitsEqual = [](const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
      return std::memcmp(a.data(), b.data(), sizeof(double) * 3) == 0;
    };
    std::size_t differ = 0;
    for (int r = 0; r < dem.height; ++r) {
      for (int c = 0; c < dem.width; ++c) {
        const std::size_t i = static_cast<std::size_t>(r) * dem.width + c;
        const Eigen::Vector3d& v = whole.mesh.vertices[i];
        differ += !bitsEqual(flat.at(c + 0.5, r + 0.5, v.z()), v);
      }
    }
    EXPECT_EQ(differ, 0u) << dem.path;
    const qota::PixelWindow window{dem.width / 3, dem.height / 4, dem.width / 2, dem.height / 2};
    std::vector<double> z;
    std::vector<std::uint8_t> valid;
    for (int r = window.row; r < window.row + window.height; ++r) {
      for (int c = window.col; c < window.col + window.width; ++c) {
        const std::size_t i = static_cast<std::size_t>(r) * dem.width + c;
        z.push_back(whole.mesh.vertices[i].z()), valid.push_back(whole.valid[i]);
      }
    }
    const LocalFrame part = qota::windowFrame(basis, window, z, valid);
    const LocalFrame shell = qota::gridFrame(basis, window, valid);
    EXPECT_TRUE(shell.mesh.vertices.empty());
    EXPECT_EQ(shell.pixelCount(), part.pixelCount());
    for (std::size_t i = 0; i < part.pixelCount(); ++i) {
      const double col = window.col + static_cast<int>(i % window.width) + 0.5;
      const double row = window.row + static_cast<int>(i / window.width) + 0.5;
      differ += !bitsEqual(flat.at(col, row, z[i]), part.mesh.vertices[i]);
    }
    EXPECT_EQ(differ, 0u) << dem.path << ", a window";
  };
  qota::FrameOptions pixels;
  pixels.pixelSize = 7.5;
  qota::DemTerrain grid = gridDem(31, 23, qota::fractalHeightfield(31, 23, 1.0, 40, 3).z);
  expectSame(grid, pixels);
  qota::FrameOptions flat;
  flat.flat = true;
  const qota::DemTerrain rainier = qota::loadDem(QOTA_DATA_DIR "/mt_rainier_90m.tif", {.lonLatAsCartesian = true});
  expectSame(rainier, flat);
  expectSame(qota::loadDem(QOTA_DATA_DIR "/SainteHelens.dem", {}), flat);
  // And the points themselves, from elsewhere: a pixel grid's centres 7.5 m apart about the
  // middle pixel; a projected grid's as GDAL's geotransform places them (metres); degrees scaled
  // so that a pixel's step at the centre is GeographicLib's geodesic over it.
  const auto placement = [](const qota::DemTerrain& dem, const qota::FrameOptions& options) {
    qota::FrameBasis basis;
    qota::localFrame(dem, options, basis);
    return qota::FlatPlacement(basis);
  };
  const qota::FlatPlacement onGrid = placement(grid, pixels);
  for (const auto& [c, r] : {std::pair{0, 0}, std::pair{15, 11}, std::pair{30, 22}, std::pair{7, 19}}) {
    const Eigen::Vector3d p = onGrid.at(c + 0.5, r + 0.5, 12.0);
    EXPECT_NEAR(p.x(), (c - 15) * 7.5, 1e-12);
    EXPECT_NEAR(p.y(), -(r - 11) * 7.5, 1e-12);
    EXPECT_EQ(p.z(), 12.0);
  }
  const qota::DemTerrain helens = qota::loadDem(QOTA_DATA_DIR "/SainteHelens.dem", {});
  const qota::FlatPlacement projected = placement(helens, flat);
  const auto gdal = [&](double c, double r) {
    double x = 0, y = 0;
    GDALApplyGeoTransform(const_cast<double*>(helens.geotransform.data()), c, r, &x, &y);
    return Eigen::Vector2d(x, y);
  };
  const Eigen::Vector3d a = projected.at(3.5, 4.5, 0), b = projected.at(200.5, 300.5, 0);
  EXPECT_LT(((b - a).head<2>() - (gdal(200.5, 300.5) - gdal(3.5, 4.5))).norm(), 1e-6);
  const qota::FlatPlacement degrees = placement(rainier, flat);
  const double cc = (rainier.width - 1) / 2.0 + 0.5, cr = (rainier.height - 1) / 2.0 + 0.5;
  const Eigen::Vector2d centre = [&] {
    double lon = 0, lat = 0;
    GDALApplyGeoTransform(const_cast<double*>(rainier.geotransform.data()), cc, cr, &lon, &lat);
    return Eigen::Vector2d(lon, lat);
  }();
  const GeographicLib::Geodesic& wgs84 = GeographicLib::Geodesic::WGS84();
  double east = 0, north = 0;
  wgs84.Inverse(centre.y(), centre.x(), centre.y(), centre.x() + rainier.geotransform[1], east);
  wgs84.Inverse(centre.y(), centre.x(), centre.y() + rainier.geotransform[5], centre.x(), north);
  const Eigen::Vector3d o = degrees.at(cc, cr, 0);
  EXPECT_NEAR((degrees.at(cc + 1, cr, 0) - o).norm(), east, 1e-6 * east);
  EXPECT_NEAR((degrees.at(cc, cr + 1, 0) - o).norm(), north, 1e-6 * north);

  qota::FrameBasis curved;
  qota::localFrame(rainier, qota::FrameOptions{}, curved);
  EXPECT_THROW(qota::FlatPlacement{curved}, qota::Error);
}

// fillVoids against onion peeling as written plainly (every void left looked at in every pass):
// the same heights bit for bit and the same passes, on voids of every shape: specks, blobs, a
// band across the raster, a void with nothing known in its raster, the raster's edges.
TEST(Frame, FillVoidsIsOnionPeeling) {
  const auto peel = [](std::vector<double>& z, int w, int h, std::vector<std::uint32_t>& levels) {
    levels.assign(z.size(), 0);
    std::vector<std::size_t> todo;
    for (std::size_t i = 0; i < z.size(); ++i) {
      if (!std::isfinite(z[i])) todo.push_back(i);
    }
    for (std::uint32_t pass = 1; !todo.empty(); ++pass) {
      std::vector<std::pair<std::size_t, double>> fills;
      std::vector<std::size_t> still;
      for (std::size_t i : todo) {
        const int c = static_cast<int>(i % w), r = static_cast<int>(i / w);
        double sum = 0;
        int count = 0;
        for (int dr = -1; dr <= 1; ++dr) {
          for (int dc = -1; dc <= 1; ++dc) {
            const int cc = c + dc, rr = r + dr;
            if ((dr || dc) && cc >= 0 && rr >= 0 && cc < w && rr < h && std::isfinite(z[rr * w + cc])) {
              sum += z[rr * w + cc], ++count;
            }
          }
        }
        if (count) {
          fills.emplace_back(i, sum / count);
        } else {
          still.push_back(i);
        }
      }
      if (fills.empty()) {
        for (std::size_t i : still) z[i] = 0, levels[i] = qota::kNeverFilled;
        break;
      }
      for (const auto& [i, v] : fills) z[i] = v, levels[i] = pass;
      todo.swap(still);
    }
  };
  std::mt19937_64 rng(17);
  for (int k = 0; k < 60; ++k) {
    const int w = 1 + static_cast<int>(rng() % 70), h = 1 + static_cast<int>(rng() % 50);
    std::vector<double> z(static_cast<std::size_t>(w) * h);
    for (double& v : z) v = std::uniform_real_distribution<double>(-50, 3000)(rng);
    const int kind = k % 5;
    for (int r = 0; r < h; ++r) {
      for (int c = 0; c < w; ++c) {
        double& v = z[static_cast<std::size_t>(r) * w + c];
        const bool speck = rng() % 7 == 0;
        const bool blob = std::hypot(c - w / 3.0, r - h / 2.0) < 0.3 * std::min(w, h) + 1;
        const bool band = c > w / 4 && c < w / 2;
        if ((kind == 0 && speck) || (kind == 1 && blob) || (kind == 2 && (band || speck)) || kind == 3 ||
            (kind == 4 && (blob || c == 0 || r == h - 1))) {
          v = k % 2 ? NAN : INFINITY;
        }
      }
    }
    std::vector<double> want = z, got = z;
    std::vector<std::uint32_t> wantLevels, gotLevels;
    peel(want, w, h, wantLevels);
    qota::fillVoids(got, w, h, &gotLevels);
    ASSERT_EQ(std::memcmp(want.data(), got.data(), want.size() * sizeof(double)), 0) << "case " << k;
    ASSERT_EQ(wantLevels, gotLevels) << "case " << k;
  }
}

TEST(Shadow, CurvatureLowersDistantTerrain) {
  // On the ellipsoid, terrain far away drops below the tangent plane (about 8 m at 10 km), so
  // fewer pixels are shaded at a low sun than on the flat frame.
  const qota::DemTerrain dem = qota::loadDem(QOTA_DATA_DIR "/mt_rainier_90m.tif", {.lonLatAsCartesian = true});
  qota::FrameOptions overEllipsoid;  // (the curvature alone: no geoid's undulation)
  overEllipsoid.heightRef = "ellipsoid";
  const LocalFrame curved = qota::localFrame(dem, overEllipsoid), flat = qota::localFrame(dem, true);
  EXPECT_GT(curved.mesh.vertices[0].z(), -1000.0);
  EXPECT_LT(curved.mesh.vertices[0].z(), flat.mesh.vertices[0].z());
  // The far corner sinks below the tangent plane by about d^2 / 2R.
  const std::size_t i = 1200;  // north-east corner, about 47 km from the centre
  const double d = curved.mesh.vertices[i].head<2>().norm();
  EXPECT_NEAR(flat.mesh.vertices[i].z() - curved.mesh.vertices[i].z(), d * d / (2 * 6371000.0),
              0.02 * d * d / (2 * 6371000.0));
}

// --- The tool -----------------------------------------------------------------------------------

std::filesystem::path scratch(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() / "qota_shadow_tests";
  std::filesystem::create_directories(dir);
  return dir / name;
}

TEST(ShadowTool, WritesAGeoreferencedMaskAndPreview) {
  qota::tools::ShadowOptions o;
  o.source = QOTA_DATA_DIR "/SainteHelens.dem";
  o.output = scratch("helens.tif").string();
  o.png = scratch("helens.png").string();
  o.time = "1980-09-06T09:00";
  o.tz = "-07:00";
  std::ostringstream out, err;
  ASSERT_EQ(qota::tools::shadow(o, out, err), 0) << err.str();
  EXPECT_NE(out.str().find("shadow reach: "), std::string::npos) << out.str();
  qota::ensureGdalRegistered();
  std::unique_ptr<GDALDataset> ds(GDALDataset::Open(o.output.c_str(), GDAL_OF_RASTER));
  ASSERT_NE(ds, nullptr);
  EXPECT_EQ(ds->GetRasterXSize(), 327);
  EXPECT_EQ(ds->GetRasterBand(1)->GetRasterDataType(), GDT_Byte);
  EXPECT_EQ(ds->GetRasterBand(1)->GetNoDataValue(), 128);
  double gt[6];
  ds->GetGeoTransform(gt);
  EXPECT_EQ(gt[0], 557805);
  std::vector<std::uint8_t> v(327 * 468);
  ASSERT_EQ(ds->GetRasterBand(1)->RasterIO(GF_Read, 0, 0, 327, 468, v.data(), 327, 468, GDT_Byte, 0, 0), CE_None);
  std::size_t lit = 0, dark = 0, none = 0;
  for (auto x : v) lit += x == 255, dark += x == 0, none += x == 128;
  EXPECT_EQ(lit + dark + none, v.size());
  EXPECT_GT(dark, 100u);
  EXPECT_GT(lit, dark);
  EXPECT_TRUE(std::filesystem::exists(o.png));
}

TEST(ShadowTool, HoursOfSunlight) {
  qota::tools::ShadowOptions o;
  o.source = QOTA_DATA_DIR "/SainteHelens.dem";
  o.output = scratch("hours.tif").string();
  o.time = "2024-06-21";
  o.tz = "-07:00";
  o.hours = std::array<double, 3>{4, 22, 1};
  o.quiet = true;
  std::ostringstream out, err;
  ASSERT_EQ(qota::tools::shadow(o, out, err), 0) << err.str();
  std::unique_ptr<GDALDataset> ds(GDALDataset::Open(o.output.c_str(), GDAL_OF_RASTER));
  ASSERT_NE(ds, nullptr);
  EXPECT_EQ(ds->GetRasterBand(1)->GetRasterDataType(), GDT_Float32);
  double minmax[2];
  ds->GetRasterBand(1)->ComputeRasterMinMax(FALSE, minmax);
  EXPECT_GE(minmax[0], 0.0);
  EXPECT_LE(minmax[1], 16.0);  // about 15.5 h of daylight at 46 N at midsummer
  EXPECT_GT(minmax[1], 12.0);
}

// Web Mercator pixels 100,000 km wide: PROJ still gives every pixel a longitude and latitude
// (wrapped round the globe, or the pole itself), so on the ellipsoid the raster would fold onto
// itself or stack at the pole (minutes of search, a meaningless mask). The frame refuses it and
// names the pixel; --flat takes it as it is.
TEST(ShadowTool, ARasterOutsideItsProjectionIsRefused) {
  const auto path = scratch("beyond_mercator.tif");
  qota::test::RasterSpec spec;
  spec.width = 30, spec.height = 12;
  spec.geotransform = {0, 1e8, 0, 0, 0, -1e8};
  spec.crs = "EPSG:3857";
  spec.bands = {std::vector<double>(360)};
  for (std::size_t i = 0; i < 360; ++i) spec.bands[0][i] = static_cast<double>((i * 37) % 101);
  qota::test::writeRaster(path, spec);
  std::ostringstream out, err;
  qota::tools::ShadowOptions o;
  o.source = path.string();
  o.output = scratch("beyond_mercator_shadow.tif").string();
  o.azimuth = 238, o.altitude = 29;
  o.quiet = true;
  std::filesystem::remove(o.output);
  EXPECT_EQ(qota::tools::shadow(o, out, err), 2);
  EXPECT_NE(err.str().find("outside the domain of the raster's projection"), std::string::npos) << err.str();
  EXPECT_NE(err.str().find("pixel (0, 0)"), std::string::npos) << err.str();
  EXPECT_FALSE(std::filesystem::exists(o.output));
  o.flat = true;
  err.str("");
  EXPECT_EQ(qota::tools::shadow(o, out, err), 0) << err.str();
  EXPECT_TRUE(std::filesystem::exists(o.output));
}

TEST(ShadowTool, BadInputIsAClearErrorAndLeavesNoFile) {
  std::ostringstream out, err;
  qota::tools::ShadowOptions o;
  o.source = "/no/such/dem.tif";
  o.output = scratch("none.tif").string();
  EXPECT_EQ(qota::tools::shadow(o, out, err), 2);
  EXPECT_NE(err.str().find("/no/such/dem.tif"), std::string::npos);

  o.source = QOTA_DATA_DIR "/SainteHelens.dem";
  o.output = "/no/such/dir/out.tif";
  err.str("");
  EXPECT_EQ(qota::tools::shadow(o, out, err), 2);
  EXPECT_NE(err.str().find("/no/such/dir/out.tif"), std::string::npos) << err.str();

  o.output = scratch("twice.tif").string();
  std::filesystem::remove(o.output);
  o.azimuth = 100;
  o.time = "2024-01-01T12:00Z";
  err.str("");
  EXPECT_EQ(qota::tools::shadow(o, out, err), 2);
  EXPECT_NE(err.str().find("give one light"), std::string::npos);
  EXPECT_FALSE(std::filesystem::exists(o.output));

  // Below the horizon: documented, every pixel dark, success.
  o.time.clear();
  o.altitude = -5;
  o.quiet = true;
  err.str("");
  EXPECT_EQ(qota::tools::shadow(o, out, err), 0);
  EXPECT_NE(err.str().find("below the horizon"), std::string::npos);

  // A raster without georeferencing: an error unless --pixel-size gives its scale.
  const auto bare = scratch("bare.tif");
  {
    GDALDriver* drv = GetGDALDriverManager()->GetDriverByName("GTiff");
    std::unique_ptr<GDALDataset> ds(drv->Create(bare.c_str(), 20, 20, 1, GDT_Float32, nullptr));
    std::vector<float> z(400, 5.0f);
    ASSERT_EQ(ds->GetRasterBand(1)->RasterIO(GF_Write, 0, 0, 20, 20, z.data(), 20, 20, GDT_Float32, 0, 0), CE_None);
  }
  o.source = bare.string();
  o.altitude = 30;
  err.str("");
  EXPECT_EQ(qota::tools::shadow(o, out, err), 2);
  EXPECT_NE(err.str().find("--pixel-size"), std::string::npos) << err.str();
  o.pixelSize = 2;
  EXPECT_EQ(qota::tools::shadow(o, out, err), 0) << err.str();
  o.azimuth.reset();
  o.altitude.reset();
  o.time = "2024-01-01T12:00Z";
  err.str("");
  EXPECT_EQ(qota::tools::shadow(o, out, err), 2);
  EXPECT_NE(err.str().find("no coordinate reference system"), std::string::npos) << err.str();
}

}  // namespace
