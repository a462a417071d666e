// ShadowTiles' private parts (lib/features only), shared by its files: shadow_tiles.cpp (the pass
// over the heights, windows, masks and hours), shadow_tiles_plan.cpp (halos, reaches and tile
// sizes for a memory budget), shadow_tiles_state.cpp (the state written for a batch's jobs).
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "qota/error.hpp"
#include "qota/shadow_tiles.hpp"

namespace qota::tiles {

inline constexpr double kDeg = M_PI / 180.0;

// The grid's local geometry at a pixel: the frame points of the pixel and its east and south
// neighbours at height 0, and the body's up there.
struct Local {
  Eigen::Vector3d origin, up, east, south;  // east, south: one column, one row on
};

inline Local localAt(const FrameBasis& basis, int col, int row) {
  const int w = basis.raster.width, h = basis.raster.height;
  const int c = std::clamp(col, 0, std::max(0, w - 2)), r = std::clamp(row, 0, std::max(0, h - 2));
  const PixelWindow square{c, r, std::min(2, w), std::min(2, h)};
  const LocalFrame f = windowFrame(basis, square, std::vector<double>(square.pixelCount(), 0.0),
                                   std::vector<std::uint8_t>(square.pixelCount(), 1));
  const auto& v = f.mesh.vertices;
  Local l;
  l.origin = v[0];
  l.up = f.upAt(v[0]);
  l.east = square.width > 1 ? Eigen::Vector3d(v[1] - v[0]) : Eigen::Vector3d::Zero();
  l.south = square.height > 1 ? Eigen::Vector3d(v[square.width] - v[0]) : Eigen::Vector3d::Zero();
  return l;
}

}  // namespace qota::tiles

namespace qota {

struct ShadowTiles::Source {
  std::unique_ptr<DemWindows> windows;  // when reading a file
  HeightReader reader;
  mutable std::mutex lock;  // one read at a time
  // The heights of w; with `blocks`, read by whole blocks and checked against their hashes (the
  // raster may not be the one the hashes were made from: a restored state's, or a file changed).
  void read(const PixelWindow& w, std::vector<double>& out, const HeightBlocks* blocks, const std::string& path) const {
    const std::lock_guard<std::mutex> guard(lock);
    const PixelWindow cover = blocks ? blocks->alignedOut(w) : w;
    std::vector<double> all;
    std::vector<double>& into = cover == w ? out : all;
    into.resize(cover.pixelCount());
    reader(cover, into);
    if (into.size() != cover.pixelCount()) {
      throw Error("a height reader gave " + std::to_string(into.size()) + " heights for " +
                  std::to_string(cover.pixelCount()) + " pixels");
    }
    if (blocks) blocks->check(cover, into, path);
    if (cover == w) return;
    out.resize(w.pixelCount());
    for (int r = 0; r < w.height; ++r) {
      const std::size_t from = static_cast<std::size_t>(r + w.row - cover.row) * cover.width + (w.col - cover.col);
      std::copy_n(all.begin() + static_cast<std::ptrdiff_t>(from), w.width,
                  out.begin() + static_cast<std::ptrdiff_t>(r) * w.width);
    }
  }
};

}  // namespace qota
