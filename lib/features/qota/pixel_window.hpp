// A rectangle of a raster's pixels, the unit tiled work is cut into.
#pragma once

#include <cstddef>

namespace qota {

// A rectangle of a raster's pixels: columns [col, col + width), rows [row, row + height).
struct PixelWindow {
  int col = 0, row = 0, width = 0, height = 0;
  std::size_t pixelCount() const { return static_cast<std::size_t>(width) * static_cast<std::size_t>(height); }
  bool operator==(const PixelWindow&) const = default;
};

// The name of qota 0.2 (whose shadow code said "cell" for a pixel).
using CellWindow [[deprecated("use qota::PixelWindow")]] = PixelWindow;

}  // namespace qota
