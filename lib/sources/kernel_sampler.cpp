#include "qota/kernel_sampler.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "qota/error.hpp"

namespace qota {

Resampling resamplingNamed(std::string_view name) {
  if (name == "triangle") return Resampling::Triangle;
  if (name == "nearest") return Resampling::Nearest;
  if (name == "bilinear") return Resampling::Bilinear;
  if (name == "cubic") return Resampling::Cubic;
  throw Error("resampling '" + std::string(name) + "' is not one of triangle, nearest, bilinear, cubic");
}

const char* resamplingName(Resampling r) {
  switch (r) {
    case Resampling::Triangle:
      return "triangle";
    case Resampling::Nearest:
      return "nearest";
    case Resampling::Bilinear:
      return "bilinear";
    case Resampling::Cubic:
      return "cubic";
  }
  return "?";
}

namespace {

constexpr double kVoid = std::numeric_limits<double>::quiet_NaN();

// Keys' cubic convolution kernel with a = -0.5 (Catmull-Rom).
double cubicWeight(double t) {
  const double a = std::fabs(t);
  if (a <= 1) return (1.5 * a - 2.5) * a * a + 1;
  if (a <= 2) return ((-0.5 * a + 2.5) * a - 4) * a + 2;
  return 0;
}

}  // namespace

KernelSampler::KernelSampler(const std::string& path, int band, Resampling rule)
    : windows_(path, {.band = band, .lonLatAsCartesian = true}), rule_(rule) {
  if (rule == Resampling::Triangle) {
    throw Error("KernelSampler: the triangle rule is RasterSampler's (the exact surface)");
  }
  const DemTerrain& d = windows_.dem();
  // A raster narrower than the kernel takes the next smaller one (GDAL's rule; every raster qota
  // opens has 2 x 2 pixels at least, enough for bilinear).
  if (rule_ == Resampling::Cubic && (d.width < 4 || d.height < 4)) rule_ = Resampling::Bilinear;
  inverse_ = d.inverseGeotransform();
}

const std::vector<double>& KernelSampler::block(int bx, int by) {
  const std::uint64_t key = (static_cast<std::uint64_t>(by) << 32) | static_cast<std::uint32_t>(bx);
  if (auto it = blocks_.find(key); it != blocks_.end()) return it->second;
  if (blocks_.size() >= maxBlocks_) blocks_.clear();  // (points come in batches: a fresh start is cheap)
  const DemTerrain& d = windows_.dem();
  const int col = bx * kBlock, row = by * kBlock;
  std::vector<double> values;
  windows_.read(col, row, std::min(kBlock, d.width - col), std::min(kBlock, d.height - row), values);
  return blocks_.emplace(key, std::move(values)).first->second;
}

double KernelSampler::pixel(int col, int row) {
  const DemTerrain& d = windows_.dem();
  col = std::clamp(col, 0, d.width - 1), row = std::clamp(row, 0, d.height - 1);
  const std::vector<double>& b = block(col / kBlock, row / kBlock);
  const int w = std::min(kBlock, d.width - col / kBlock * kBlock);
  const double v = b[static_cast<std::size_t>(row % kBlock) * w + col % kBlock];
  return std::isfinite(v) ? v : kVoid;
}

std::optional<double> KernelSampler::height(double x, double y) {
  const DemTerrain& d = windows_.dem();
  const auto [col, row] = d.pixelOf(d.turnedOnto(x), y, inverse_);
  if (!(col >= 0 && col <= d.width && row >= 0 && row <= d.height)) return std::nullopt;
  double h = kVoid;
  if (rule_ == Resampling::Nearest) {
    h = pixel(std::min(static_cast<int>(col), d.width - 1), std::min(static_cast<int>(row), d.height - 1));
  } else {
    // Centre coordinates: pixel (i, j)'s centre at (i, j).
    const double cx = col - 0.5, cy = row - 0.5;
    const int i = static_cast<int>(std::floor(cx)), j = static_cast<int>(std::floor(cy));
    const double dx = cx - i, dy = cy - j;
    if (rule_ == Resampling::Bilinear) {
      const double v00 = pixel(i, j), v10 = pixel(i + 1, j), v01 = pixel(i, j + 1), v11 = pixel(i + 1, j + 1);
      // (a void is NaN, and NaN spreads: any void leaves no height)
      h = (v00 * (1 - dx) + v10 * dx) * (1 - dy) + (v01 * (1 - dx) + v11 * dx) * dy;
    } else {
      double sum = 0, weights = 0;
      for (int b = -1; b <= 2; ++b) {
        const double wy = cubicWeight(b - dy);
        for (int a = -1; a <= 2; ++a) {
          const double v = pixel(i + a, j + b);
          if (std::isnan(v)) continue;
          const double w = cubicWeight(a - dx) * wy;
          sum += v * w, weights += w;
        }
      }
      if (weights != 0) h = sum / weights;
    }
  }
  if (std::isnan(h)) return std::nullopt;
  return h;
}

void KernelSampler::heights(std::span<const double> xs, std::span<const double> ys,
                            std::span<std::optional<double>> out) {
  if (xs.size() != ys.size() || xs.size() != out.size()) {
    throw Error("KernelSampler::heights: " + std::to_string(xs.size()) + " x, " + std::to_string(ys.size()) + " y, " +
                std::to_string(out.size()) + " out");
  }
  for (std::size_t k = 0; k < xs.size(); ++k) out[k] = height(xs[k], ys[k]);
}

}  // namespace qota
