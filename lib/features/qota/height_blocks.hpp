// The fingerprint of a raster's heights, block by block: what work checks the heights against
// when it did not read them all itself (tiles restored from a state file, a Dask task given its
// block's heights, tiles assembled from several jobs). A path names a file, not what it holds:
// another raster under the same name, another band, scale, offset or nodata value gives other
// heights, and so other hashes.
//
// The raster is cut into square blocks of side() pixels from its top-left pixel (the last column
// and row of blocks cut by the raster's edges). A block's hash is XXH3 (64 bits) of its heights
// row by row, as doubles in the raster's unit with its scale and offset applied and NaN where
// there is no data (what DemWindows::read gives), every NaN written as one quiet NaN and -0 as
// +0, so that equal heights always hash equally. A block that differs in any pixel has another
// hash except with a chance of about 2^-64. XXH3 is not a cryptographic hash: it tells a wrong
// raster from the right one, not a forgery made to match.
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "qota/pixel_window.hpp"

namespace qota {

class HeightBlocks {
 public:
  // At most this many blocks, so that a state file stays small (16 hexadecimal digits a block).
  static constexpr int kMostBlocks = 1 << 18;

  HeightBlocks() = default;
  // Blocks for a raster of this size: the side is the least multiple of 16, at least 64, that
  // makes at most kMostBlocks blocks. No hashes yet (addRows).
  HeightBlocks(int width, int height);
  // Restored: the hashes of a raster of this size in blocks of `side`. Throws qota::Error when
  // they cannot be that (a size below 1, a side that is not a multiple of 16 of at least 64, or
  // another number of hashes than of blocks).
  HeightBlocks(int width, int height, int side, std::vector<std::uint64_t> hashes);

  int side() const { return side_; }
  int width() const { return width_; }
  int height() const { return height_; }
  int across() const { return (width_ + side_ - 1) / side_; }
  int down() const { return (height_ + side_ - 1) / side_; }
  // Every block hashed (all rows added, or restored).
  bool complete() const { return rowsAdded_ == height_ && height_ > 0; }
  // The blocks' hashes, row-major; complete() first.
  const std::vector<std::uint64_t>& hashes() const { return hashes_; }
  // One hash of the whole raster's heights: of its size, the side and every block's hash.
  std::uint64_t whole() const;

  // The pass over the heights: rows [row, row + count) of the whole width (width * count values,
  // row-major), given in order from row 0. Throws qota::Error for rows out of order.
  void addRows(int row, int count, const std::vector<double>& heights);

  // The least and greatest heights with data (not NaN) in the blocks that meet `w`, in the
  // raster's unit: bounds of the heights in w ({+inf, -inf} where the blocks have no data).
  std::pair<double, double> rangeOver(const PixelWindow& w) const;
  // Every block's least and greatest height, as rangeOver gives them, row-major (restore: the
  // same, given back to setRanges).
  const std::vector<double>& lows() const { return lows_; }
  const std::vector<double>& highs() const { return highs_; }
  // Throws qota::Error unless both have one value a block, each low at most its high (or the
  // pair {+inf, -inf}).
  void setRanges(std::vector<double> lows, std::vector<double> highs);

  // The smallest window made of whole blocks (cut by the raster's edges) that holds `w` (a window
  // on the raster).
  PixelWindow alignedOut(const PixelWindow& w) const;
  bool aligned(const PixelWindow& w) const { return alignedOut(w) == w; }
  // Checks the heights of `window` (row-major, window made of whole blocks) against the hashes.
  // Throws qota::Error when a block differs, naming `what` (the raster, for the message) and the
  // block's pixels.
  void check(const PixelWindow& window, const std::vector<double>& heights, const std::string& what) const;

 private:
  int width_ = 0, height_ = 0, side_ = 64;
  int rowsAdded_ = 0;
  std::vector<std::uint64_t> hashes_;
  std::vector<double> lows_, highs_;  // per block, over its pixels with data
  std::vector<std::uint64_t> open_;   // addRows: the current row of blocks' XXH3 states, as raw bytes
};

// XXH3 (64 bits) of bytes given in parts: the same hash as hashOf of them all at once.
class StreamingHash {
 public:
  StreamingHash();
  ~StreamingHash();
  StreamingHash(const StreamingHash&) = delete;
  StreamingHash& operator=(const StreamingHash&) = delete;
  void add(const void* data, std::size_t bytes);
  std::string hex() const;  // hexOf the hash so far

 private:
  void* state_;
};

// A checksum of a text (XXH3, 128 bits) as 32 hexadecimal digits: what a state file or a tile's
// metadata carries so that an edit or damage is refused.
std::string checksumOf(const std::string& text);
// A hash (XXH3, 64 bits) of bytes as 16 hexadecimal digits, and the digits of a 64-bit hash.
std::string hashOf(const void* data, std::size_t bytes);
std::string hexOf(std::uint64_t hash);

}  // namespace qota
