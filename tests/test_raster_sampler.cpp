// RasterSampler (tile by tile) against the surface dem.hpp documents, computed here from GDAL's
// read of the pixels, and against the whole terrain (loadDem + CartesianIndex, the path qota
// sample took before): the same height as the whole terrain, bit for bit,
// at random points, pixel centres, cell sides, tile sides, beside and inside holes, with tiles
// small enough that boundaries are everywhere and a cache small enough to evict.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <random>
#include <vector>

#include "qota/dem.hpp"
#include "qota/raster_sampler.hpp"
#include "qota/terrain.hpp"
#include "raster_files.hpp"

namespace {

using qota::DemTerrain;
using qota::RasterSampler;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// The whole terrain's answer at world (x, y) (already on the surface): the top, or the nearest
// at or below z, as the world point's z.
std::optional<double> wholeAnswer(const qota::CartesianIndex& index, double x, double y, const double* z) {
  const Eigen::Vector3d m = index.mapping().toMapped(Eigen::Vector3d(x, y, z ? *z : 0.0));
  const auto hit = z ? index.below(m.x(), m.y(), m.z()) : index.top(m.x(), m.y());
  if (!hit) return std::nullopt;
  return hit->world.z();
}

// The documented surface (dem.hpp) computed here from GDAL's own read of the band, without qota:
// the pixel coordinates through GDAL's inverse geotransform, the cell under them, its half
// (split from the top-left to the bottom-right centre) and the linear interpolation of its three
// centres' values, scaled; std::nullopt on a nodata corner or off the cells. `near`: within
// 1e-7 cell of the half's sides, where a neighbour may answer (the value agrees to rounding).
std::optional<double> documentedHeight(const qota::test::RasterValues& r, double scale, double offset,
                                       std::optional<double> nodata, double x, double y, bool& near) {
  double gt[6], inv[6];
  std::copy(r.geotransform.begin(), r.geotransform.end(), gt);
  if (!GDALInvGeoTransform(gt, inv)) return std::nullopt;
  const double fc = inv[0] + x * inv[1] + y * inv[2] - 0.5, fr = inv[3] + x * inv[4] + y * inv[5] - 0.5;
  // (A point the outer half-pixel rule put on the centres' lines may round a hair outside them.)
  const double slack = 1e-9;
  if (!(fc >= -slack && fr >= -slack && fc <= r.width - 1 + slack && fr <= r.height - 1 + slack)) return std::nullopt;
  const int c = std::clamp(static_cast<int>(std::floor(fc)), 0, r.width - 2);
  const int row = std::clamp(static_cast<int>(std::floor(fr)), 0, r.height - 2);
  const double a = fc - c, b = fr - row;  // within the cell, 0..1
  near = std::min({a, b, 1 - a, 1 - b, std::fabs(a - b)}) < 1e-7;
  // (TL, BL, BR) where b > a, else (TL, BR, TR): barycentric weights of the three centres.
  const double tl = r.at(c, row), tr = r.at(c + 1, row), bl = r.at(c, row + 1), br = r.at(c + 1, row + 1);
  const bool lower = b > a;
  const double v0 = tl, v1 = lower ? bl : tr, v2 = br;
  const double w1 = lower ? b - a : a - b, w2 = lower ? a : b, w0 = 1 - w1 - w2;
  for (const double v : {v0, v1, v2}) {
    if (!std::isfinite(v) || (nodata && v == *nodata)) return std::nullopt;
  }
  return (w0 * v0 + w1 * v1 + w2 * v2) * scale + offset;
}

// Points that find every special place of a raster: random ones over the footprint and beyond
// it, every pixel centre of a few rows and columns, the midpoints of cell sides and diagonals,
// the outer half pixel, all put on the surface by the outer half-pixel rule (off: NaN).
void makePoints(const DemTerrain& dem, std::uint64_t seed, std::vector<double>& xs, std::vector<double>& ys,
                int random = 20000) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> uc(-0.3, dem.width + 0.3), ur(-0.3, dem.height + 0.3);
  std::vector<std::array<double, 2>> pix;  // (col, row) in pixel coordinates
  for (int i = 0; i < random; ++i) pix.push_back({uc(rng), ur(rng)});
  for (int r = 0; r < dem.height; r += std::max(1, dem.height / 7)) {
    for (int c = 0; c < dem.width; ++c) {
      pix.push_back({c + 0.5, r + 0.5});            // a centre
      pix.push_back({c + 1.0, r + 0.5});            // a row's side
      pix.push_back({c + 0.5, r + 1.0});            // a column's side
      pix.push_back({c + 1.0, r + 1.0});            // a diagonal's midpoint
      pix.push_back({c + 0.75, r + 0.75 + 1e-12});  // beside the diagonal
    }
  }
  for (int c = 0; c < dem.width; c += std::max(1, dem.width / 7)) {
    for (int r = 0; r < dem.height; ++r) pix.push_back({c + 0.5, r + 0.9}), pix.push_back({c + 0.2, r + 0.5});
  }
  for (const auto& [c, r] : pix) {
    const auto xy = dem.pixelCentre(c - 0.5, r - 0.5);
    const auto p = dem.surfacePoint(xy[0], xy[1]);
    xs.push_back(p ? (*p)[0] : kNaN);
    ys.push_back(p ? (*p)[1] : kNaN);
  }
}

// Every point, top and below a random z, from a sampler with the given tile size and cache.
// And every top answer against the documented surface (documentedHeight), to 1e-6.
// random: how many random points (many make the large tiles' lean grids answer most points);
// leanTiles: set to the lean tiles the sampler built.
void expectSameAsWhole(const std::string& path, int band, int tileSize, std::uint64_t cacheBytes, std::uint64_t seed,
                       double scale = 1, double offset = 0, int random = 20000, std::uint64_t* leanTiles = nullptr) {
  const DemTerrain dem = qota::loadDem(path, {.band = band, .lonLatAsCartesian = true});
  const qota::CartesianIndex whole(dem.mesh, dem.mapping);
  RasterSampler sampler(path, {.band = band, .cacheBytes = cacheBytes, .tileSize = tileSize});
  std::vector<double> xs, ys;
  makePoints(dem, seed, xs, ys, random);
  std::mt19937_64 rng(seed + 1);
  double lo = INFINITY, hi = -INFINITY;
  for (const auto& v : dem.mesh.vertices) {
    if (std::isfinite(v.z())) lo = std::min(lo, v.z()), hi = std::max(hi, v.z());
  }
  std::uniform_real_distribution<double> uz(lo - 1, hi + 1);
  std::vector<double> zs(xs.size());
  for (double& z : zs) z = uz(rng);
  std::vector<std::optional<double>> top(xs.size()), below(xs.size());
  sampler.heights(xs, ys, {}, top);
  sampler.heights(xs, ys, zs, below);
  const qota::test::RasterValues raw = qota::test::readRaster(path, band == 0 ? 1 : band);
  int hits = 0, checked = 0;
  for (std::size_t i = 0; i < xs.size(); ++i) {
    bool near = false;
    const auto documented = documentedHeight(raw, scale, offset, dem.nodata, xs[i], ys[i], near);
    if (!near) {
      ASSERT_EQ(top[i].has_value(), documented.has_value()) << "point " << i << ", tile " << tileSize;
      if (documented) {
        // The pixel coordinates of points at 1e6 carry rounding of about 1e-11 pixel: times slopes of
        // up to 1000 a pixel, 1e-8; a wrong triangle would be metres off.
        ASSERT_NEAR(*top[i], *documented, 1e-6) << "point " << i;
      }
      ++checked;
    }
    const auto want = wholeAnswer(whole, xs[i], ys[i], nullptr);
    const auto wantBelow = wholeAnswer(whole, xs[i], ys[i], &zs[i]);
    ASSERT_EQ(top[i], want) << "point " << i << " (" << xs[i] << ", " << ys[i] << "), tile " << tileSize;
    ASSERT_EQ(below[i], wantBelow) << "point " << i << " below " << zs[i] << ", tile " << tileSize;
    hits += top[i].has_value();
  }
  EXPECT_GT(hits, static_cast<int>(xs.size() / 2));
  EXPECT_GT(checked, 10000);  // (most of the 20,000 random points; the others lie on sides on purpose)
  if (cacheBytes < (1u << 20)) {
    EXPECT_LE(sampler.cachedBytes(), std::max<std::uint64_t>(cacheBytes, 1u << 20));
  }
  if (leanTiles) *leanTiles = sampler.leanTilesBuilt();
}

// A w x h raster of `values` (nodata -9999) on a rotated and sheared geotransform of 30 m pixels.
std::filesystem::path writeSheared(const std::string& name, int w, int h, const std::vector<double>& values,
                                   GDALDataType type) {
  const auto path = qota::test::scratchPath(name);
  qota::test::RasterSpec spec;
  spec.width = w, spec.height = h;
  spec.geotransform = {500000.0, 30.0, 4.0, 5200000.0, -3.0, -30.0};
  spec.bands = {values};
  spec.nodata = -9999;
  spec.type = type;
  qota::test::writeRaster(path, spec);
  return path;
}

TEST(RasterSampler, RainierTileByTileIsTheWholeTerrain) {
  // 1201 x 1201 pixels: tiles of 64 cells (19 x 19 of them), a cache of a few tiles.
  expectSameAsWhole(QOTA_DATA_DIR "/mt_rainier_90m.tif", 0, 64, 4u << 20, 1);
}

TEST(RasterSampler, HolesScaleAndTinyTiles) {
  // A 23 x 17 Int16 raster with nodata blobs across tile sides, a scale and an offset, and a
  // rotated geotransform: tiles of 1 to 5 cells, a cache of one tile.
  std::mt19937_64 rng(5);
  const int w = 23, h = 17;
  std::vector<double> v(static_cast<std::size_t>(w) * h);
  for (double& x : v) x = std::floor(std::uniform_real_distribution<double>(-300, 3000)(rng));
  for (int r = 0; r < h; ++r) {
    for (int c = 0; c < w; ++c) {
      if ((c - 6) * (c - 6) + (r - 5) * (r - 5) <= 4 || (c == 15 && r > 8) || (r == 3 && c > 17)) {
        v[static_cast<std::size_t>(r) * w + c] = -9999;
      }
    }
  }
  const auto path = writeSheared("sampler_holes.tif", w, h, v, GDT_Int16);
  {  // scale and offset on the band
    qota::ensureGdalRegistered();
    std::unique_ptr<GDALDataset> ds(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER | GDAL_OF_UPDATE));
    ds->GetRasterBand(1)->SetScale(0.25);
    ds->GetRasterBand(1)->SetOffset(-7.5);
  }
  for (int tile = 1; tile <= 5; ++tile) {
    SCOPED_TRACE(tile);
    expectSameAsWhole(path.string(), 1, tile, 1, 10 + tile, 0.25, -7.5);
  }
}

TEST(RasterSampler, LeanTilesAnswerAsTheWholeTerrain) {
  // Enough points that every large tile is built as a lean grid and answers most of them, the
  // rest (on sides, at the outer half pixel, beside holes) going to small tiles: on Rainier
  // (Int16 with nodata holes, north up: heights in float, u by column) ...
  std::uint64_t lean = 0;
  expectSameAsWhole(QOTA_DATA_DIR "/mt_rainier_90m.tif", 0, 200, 64u << 20, 21, 1, 0, 150000, &lean);
  EXPECT_EQ(lean, 36u);  // (1200 cells a side in tiles of 200: 6 x 6)
  // ... and on a sheared Float64 raster with fractional heights and holes (neither float
  // heights nor u by column), in tiles of 16 cells.
  std::mt19937_64 rng(8);
  const int w = 90, h = 70;
  std::vector<double> v(static_cast<std::size_t>(w) * h);
  for (int r = 0; r < h; ++r) {
    for (int c = 0; c < w; ++c) {
      const bool hole = (c - 30) * (c - 30) + (r - 40) * (r - 40) < 40 || (c == 61 && r > 12) ||
                        std::uniform_real_distribution<double>(0, 1)(rng) < 0.005;
      v[static_cast<std::size_t>(r) * w + c] = hole ? -9999
                                                    : 500 + 80 * std::sin(0.2 * c) * std::cos(0.15 * r) +
                                                          std::uniform_real_distribution<double>(0, 1e-3)(rng);
    }
  }
  const auto path = writeSheared("sampler_lean.tif", w, h, v, GDT_Float64);
  expectSameAsWhole(path.string(), 1, 16, 64u << 20, 22, 1, 0, 60000, &lean);
  EXPECT_EQ(lean, 30u);  // (89 x 69 cells in tiles of 16: 6 x 5)
}

TEST(RasterSampler, OneRowOrColumnIsRefusedAndOffIsNone) {
  // One row of pixel centres spans no triangle: refused, where it answered "none" at its own
  // pixel centres before.
  const auto path = qota::test::scratchPath("sampler_row.tif");
  qota::test::RasterSpec spec;
  spec.width = 9, spec.height = 1;
  spec.bands = {std::vector<double>(9, 5.0)};
  qota::test::writeRaster(path, spec);
  EXPECT_THROW(RasterSampler(path.string(), {}), qota::Error);
  EXPECT_THROW(RasterSampler("/nonexistent/qota.tif", {}), qota::Error);
  spec.width = 9, spec.height = 2;
  spec.bands = {std::vector<double>(18, 5.0)};
  qota::test::writeRaster(path, spec);
  RasterSampler sampler(path.string(), {});
  std::vector<double> xs{0.5, 4.5, 100, kNaN}, ys{-0.5, -1.5, -0.5, 0};
  std::vector<std::optional<double>> out(4, 1.0);
  sampler.heights(xs, ys, {}, out);
  EXPECT_EQ(out[0], 5.0);
  EXPECT_EQ(out[1], 5.0);
  EXPECT_FALSE(out[2].has_value());  // off the raster
  EXPECT_FALSE(out[3].has_value());  // not a point
  std::vector<std::optional<double>> small(1);
  EXPECT_THROW(sampler.heights(xs, ys, {}, small), qota::Error);
}

}  // namespace
