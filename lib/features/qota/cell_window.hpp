// A rectangle of a raster's cells, the unit tiled work is cut into.
#pragma once

#include <cstddef>

namespace qota {

// A rectangle of a raster's cells: columns [col, col + width), rows [row, row + height).
struct CellWindow {
  int col = 0, row = 0, width = 0, height = 0;
  std::size_t cellCount() const { return static_cast<std::size_t>(width) * static_cast<std::size_t>(height); }
  bool operator==(const CellWindow&) const = default;
};

}  // namespace qota
