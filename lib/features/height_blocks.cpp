// Heights hashed block by block (see qota/height_blocks.hpp).
#include "qota/height_blocks.hpp"

#define XXH_INLINE_ALL
#include <xxhash.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>

#include "qota/error.hpp"

namespace qota {
namespace {

// Equal heights, equal bits: one NaN for every NaN, +0 for -0.
inline double canonical(double v) {
  if (std::isnan(v)) return std::numeric_limits<double>::quiet_NaN();
  return v == 0 ? 0.0 : v;
}

void canonicalCopy(const double* from, std::size_t n, double* to) {
  for (std::size_t i = 0; i < n; ++i) to[i] = canonical(from[i]);
}

std::string pixelsText(int col, int row, int width, int height) {
  return "(" + std::to_string(col) + ", " + std::to_string(row) + ") + " + std::to_string(width) + " x " +
         std::to_string(height);
}

// XXH3's streaming state kept in an array of 64-bit words (aligned as XXH3_state_t needs).
constexpr std::size_t kStateWords = (sizeof(XXH3_state_t) + 7) / 8 + 8;
XXH3_state_t* stateAt(std::vector<std::uint64_t>& words, std::size_t k) {
  auto* base = reinterpret_cast<unsigned char*>(words.data() + k * kStateWords);
  const auto address = reinterpret_cast<std::uintptr_t>(base);
  const std::uintptr_t aligned = (address + 63) & ~std::uintptr_t{63};
  return reinterpret_cast<XXH3_state_t*>(base + (aligned - address));
}

}  // namespace

HeightBlocks::HeightBlocks(int width, int height) : width_(width), height_(height) {
  if (width < 1 || height < 1)
    throw Error("heights of a raster of " + std::to_string(width) + " x " + std::to_string(height) +
                " pixels cannot be hashed");
  const double pixels = static_cast<double>(width) * static_cast<double>(height);
  side_ = std::max(64, 16 * static_cast<int>(std::ceil(std::sqrt(pixels / kMostBlocks) / 16)));
  while (static_cast<std::int64_t>(across()) * down() > kMostBlocks) side_ += 16;
}

HeightBlocks::HeightBlocks(int width, int height, int side, std::vector<std::uint64_t> hashes)
    : width_(width), height_(height), side_(side), rowsAdded_(height), hashes_(std::move(hashes)) {
  if (width < 1 || height < 1 || side < 64 || side % 16 != 0) {
    throw Error("height blocks of " + std::to_string(side) + " pixels over " + std::to_string(width) + " x " +
                std::to_string(height) + " pixels: not a raster's blocks");
  }
  if (hashes_.size() != static_cast<std::size_t>(across()) * static_cast<std::size_t>(down())) {
    throw Error(std::to_string(hashes_.size()) + " block hashes for " + std::to_string(across()) + " x " +
                std::to_string(down()) + " blocks");
  }
}

std::uint64_t HeightBlocks::whole() const {
  XXH3_state_t* state = XXH3_createState();
  if (!state) throw Error("out of memory");
  XXH3_64bits_reset(state);
  const std::int64_t header[3] = {width_, height_, side_};
  XXH3_64bits_update(state, header, sizeof header);
  XXH3_64bits_update(state, hashes_.data(), hashes_.size() * sizeof(std::uint64_t));
  const std::uint64_t h = XXH3_64bits_digest(state);
  XXH3_freeState(state);
  return h;
}

void HeightBlocks::addRows(int row, int count, const std::vector<double>& heights) {
  if (row != rowsAdded_ || count < 0 || row + count > height_ ||
      heights.size() != static_cast<std::size_t>(width_) * static_cast<std::size_t>(count)) {
    throw Error("heights hashed out of order: rows " + std::to_string(row) + " + " + std::to_string(count) + " after " +
                std::to_string(rowsAdded_));
  }
  const int n = across();
  if (open_.empty()) open_.resize(static_cast<std::size_t>(n) * kStateWords);
  std::vector<double> segment(static_cast<std::size_t>(side_));
  for (int r = row; r < row + count; ++r) {
    if (r % side_ == 0) {
      for (int k = 0; k < n; ++k) XXH3_64bits_reset(stateAt(open_, k));
    }
    if (r % side_ == 0) {
      lows_.resize(lows_.size() + n, INFINITY);
      highs_.resize(highs_.size() + n, -INFINITY);
    }
    double* low = lows_.data() + lows_.size() - n;
    double* high = highs_.data() + highs_.size() - n;
    const double* line = heights.data() + static_cast<std::size_t>(r - row) * width_;
    for (int k = 0; k < n; ++k) {
      const int c0 = k * side_, w = std::min(side_, width_ - c0);
      canonicalCopy(line + c0, static_cast<std::size_t>(w), segment.data());
      XXH3_64bits_update(stateAt(open_, k), segment.data(), static_cast<std::size_t>(w) * sizeof(double));
      for (int i = 0; i < w; ++i) {
        const double v = segment[static_cast<std::size_t>(i)];
        if (v < low[k]) low[k] = v;  // (NaN never is)
        if (v > high[k]) high[k] = v;
      }
    }
    if (r + 1 == height_ || (r + 1) % side_ == 0) {
      for (int k = 0; k < n; ++k) hashes_.push_back(XXH3_64bits_digest(stateAt(open_, k)));
    }
  }
  rowsAdded_ = row + count;
  if (complete()) open_ = {};
}

std::pair<double, double> HeightBlocks::rangeOver(const PixelWindow& w) const {
  double lo = INFINITY, hi = -INFINITY;
  if (lows_.size() != hashes_.size() || !complete()) return {-INFINITY, INFINITY};  // nothing known
  const PixelWindow a = alignedOut(w);
  for (int r = a.row / side_; r < (a.row + a.height + side_ - 1) / side_; ++r) {
    for (int c = a.col / side_; c < (a.col + a.width + side_ - 1) / side_; ++c) {
      const std::size_t k = static_cast<std::size_t>(r) * across() + c;
      lo = std::min(lo, lows_[k]), hi = std::max(hi, highs_[k]);
    }
  }
  return {lo, hi};
}

void HeightBlocks::setRanges(std::vector<double> lows, std::vector<double> highs) {
  if (lows.size() != hashes_.size() || highs.size() != hashes_.size()) {
    throw Error(std::to_string(lows.size()) + " block height ranges for " + std::to_string(hashes_.size()) + " blocks");
  }
  for (std::size_t k = 0; k < lows.size(); ++k) {
    const bool empty = lows[k] == INFINITY && highs[k] == -INFINITY;
    if (!empty && !(std::isfinite(lows[k]) && std::isfinite(highs[k]) && lows[k] <= highs[k])) {
      throw Error("a block height range that no raster gives");
    }
  }
  lows_ = std::move(lows), highs_ = std::move(highs);
}

PixelWindow HeightBlocks::alignedOut(const PixelWindow& w) const {
  const int c0 = w.col / side_ * side_, r0 = w.row / side_ * side_;
  const int c1 = std::min(width_, (w.col + w.width + side_ - 1) / side_ * side_);
  const int r1 = std::min(height_, (w.row + w.height + side_ - 1) / side_ * side_);
  return {c0, r0, c1 - c0, r1 - r0};
}

void HeightBlocks::check(const PixelWindow& window, const std::vector<double>& heights, const std::string& what) const {
  if (!complete()) throw Error(what + ": its heights were not all hashed");
  if (!aligned(window) || heights.size() != window.pixelCount()) {
    throw Error(what + ": heights of pixels " + pixelsText(window.col, window.row, window.width, window.height) +
                " cannot be checked: not whole blocks of " + std::to_string(side_) + " pixels");
  }
  std::vector<double> block;
  for (int r0 = window.row; r0 < window.row + window.height; r0 += side_) {
    const int h = std::min(side_, window.row + window.height - r0);
    for (int c0 = window.col; c0 < window.col + window.width; c0 += side_) {
      const int w = std::min(side_, window.col + window.width - c0);
      block.resize(static_cast<std::size_t>(w) * h);
      for (int r = 0; r < h; ++r) {
        const double* from =
            heights.data() + static_cast<std::size_t>(r0 - window.row + r) * window.width + (c0 - window.col);
        canonicalCopy(from, static_cast<std::size_t>(w), block.data() + static_cast<std::size_t>(r) * w);
      }
      const std::uint64_t got = XXH3_64bits(block.data(), block.size() * sizeof(double));
      const std::size_t k = static_cast<std::size_t>(r0 / side_) * across() + c0 / side_;
      if (got != hashes_[k]) {
        throw Error(what + ": the heights of pixels " + pixelsText(c0, r0, w, h) +
                    " are not those the shadow tiles were made from (their hash differs): another raster, band, "
                    "scale, offset or nodata value, or a file changed since");
      }
    }
  }
}

StreamingHash::StreamingHash() : state_(XXH3_createState()) {
  if (!state_) throw Error("out of memory");
  XXH3_64bits_reset(static_cast<XXH3_state_t*>(state_));
}
StreamingHash::~StreamingHash() { XXH3_freeState(static_cast<XXH3_state_t*>(state_)); }
void StreamingHash::add(const void* data, std::size_t bytes) {
  XXH3_64bits_update(static_cast<XXH3_state_t*>(state_), data, bytes);
}
std::string StreamingHash::hex() const { return hexOf(XXH3_64bits_digest(static_cast<XXH3_state_t*>(state_))); }

std::string hexOf(std::uint64_t hash) {
  char text[17];
  std::snprintf(text, sizeof text, "%016llx", static_cast<unsigned long long>(hash));
  return text;
}

std::string hashOf(const void* data, std::size_t bytes) { return hexOf(XXH3_64bits(data, bytes)); }

std::string checksumOf(const std::string& text) {
  const XXH128_hash_t h = XXH3_128bits(text.data(), text.size());
  return hexOf(h.high64) + hexOf(h.low64);
}

}  // namespace qota
