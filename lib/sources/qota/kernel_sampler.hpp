// Heights at points by GDAL's sampling rules, beside qota's exact surface: what gdallocationinfo,
// rasterio's sample and GDAL's GDALRasterBand::InterpolateAtPoint give, so that an analyst can
// reproduce a number published with those tools.
//
// Pixel coordinates (col, row) come from the raster's inverse geotransform (a longitude turned
// onto a lon/lat grid, as DemTerrain::surfacePoint does); a point is on the raster when col is in
// [0, width] and row in [0, height], the same closed footprint as the exact surface. Heights are
// the band's values with its scale and offset applied; nodata, NaN and infinite values are voids
// (qota's rule everywhere).
// - nearest: the pixel containing the point, (floor(col), floor(row)), the last column or row for
//   a point exactly on the raster's right or bottom edge (gdallocationinfo calls that point off
//   the file). A void pixel: no height.
// - bilinear: the four pixel centres around the point (col - 0.5, row - 0.5), weighted linearly;
//   any of them void: no height (GDAL's rule).
// - cubic: the sixteen around it, weighted by Keys' cubic convolution kernel with a = -0.5 (the
//   Catmull-Rom spline, GDAL's "cubic"); void pixels are left out and the weights of the others
//   renormalised, no height when none is left (GDAL's rule).
// Beyond the outermost pixel centres the kernels read the edge pixels again (their indices
// clamped to the raster), as GDAL does. A raster narrower than 4 pixels either way samples
// bilinear for cubic, as GDAL does (qota opens no raster under 2 x 2).
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "qota/dem.hpp"

namespace qota {

enum class Resampling {
  Triangle,  // qota's exact surface: the raster's triangles (dem.hpp), through RasterSampler
  Nearest,
  Bilinear,
  Cubic,
};
// "triangle", "nearest", "bilinear", "cubic"; throws qota::Error naming the choices otherwise.
Resampling resamplingNamed(std::string_view name);
const char* resamplingName(Resampling r);

class KernelSampler {
 public:
  // Opens the raster (describeDem's checks, a lon/lat raster accepted); reads nothing yet. rule:
  // Nearest, Bilinear or Cubic. Throws qota::Error.
  KernelSampler(const std::string& path, int band, Resampling rule);

  const DemTerrain& dem() const { return windows_.dem(); }
  Resampling rule() const { return rule_; }

  // out[i]: the height at world (xs[i], ys[i]) by the rule, std::nullopt off the raster or where
  // voids leave none. Blocks of 64 x 64 pixels are read once and kept (up to cacheBytes). Not to
  // be called from two threads at once. Throws qota::Error for spans of different sizes.
  void heights(std::span<const double> xs, std::span<const double> ys, std::span<std::optional<double>> out);
  std::optional<double> height(double x, double y);

 private:
  static constexpr int kBlock = 64;
  double pixel(int col, int row);  // NaN for a void
  const std::vector<double>& block(int bx, int by);

  DemWindows windows_;
  Resampling rule_;
  std::array<double, 6> inverse_{};
  std::unordered_map<std::uint64_t, std::vector<double>> blocks_;
  std::size_t maxBlocks_ = 1024;  // 32 MiB of doubles
};

}  // namespace qota
