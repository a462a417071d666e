// The triangulation of a raster: the one place that says which triangles a grid of pixel centres
// makes, and how it is closed at its edges.
//
// Cells: one vertex per pixel centre, vertex index = row * width + col. Inner triangles: two per
// square of four centres, split along the diagonal from its top-left centre (col, row) to its
// bottom-right centre (col + 1, row + 1): (TL, BL, BR) then (TL, BR, TR), squares in row order,
// so the square (row, col) holds triangles 2 (row (width - 1) + col) and the one after.
//
// Closure, optional, each adding vertices after the pixel centres and triangles after the inner ones:
// - border: the outer half pixel. A vertex on the raster's edge beside every outermost centre
//   (and at the four corners), taking the height of the nearest centre, and the strips of squares
//   between them and the outermost centres, split the same way. The surface so reaches the
//   raster's edge flat across it: the height at a point of the outer half pixel is the height at
//   the nearest point on the outermost centres' lines (DemTerrain::surfacePoint).
// - wrapsColumns: the raster spans 360 degrees of longitude; the squares between the last column
//   and the first close the seam (and the border, if any, runs round without left and right edges).
// - northCap / southCap: the first (last) row is the last before a pole; a vertex at the pole is
//   fanned to the row (instead of a border along it).
// Every triangle keeps one winding: counter-clockwise seen with rows running down the screen
// reversed, i.e. the same turn as the inner ones, caps included.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <optional>
#include <unordered_map>
#include <vector>

#include "qota/mesh.hpp"

namespace qota {

class RasterGrid {
 public:
  struct Closure {
    bool border = false;
    bool wrapsColumns = false;
    bool northCap = false, southCap = false;
  };

  // A vertex added by the closure: where it stands in pixel coordinates (GDAL's: the raster's
  // top-left corner is (0, 0), pixel centres at + 0.5) and which pixel's height it takes, or the
  // pole it is (+1 north, -1 south; its position and height are the caller's).
  struct ExtraVertex {
    double col = 0, row = 0;
    std::uint32_t pixel = 0;
    int pole = 0;
  };

  RasterGrid() = default;
  // width, height >= 1. A closure on a grid too small to have it (a cap on a raster one row
  // high, a seam on one column) is dropped.
  RasterGrid(int width, int height, Closure closure);

  int width() const { return width_; }
  int height() const { return height_; }
  const Closure& closure() const { return closure_; }
  std::size_t pixelCount() const { return static_cast<std::size_t>(width_) * height_; }
  std::size_t innerTriangleCount() const {
    return width_ > 1 && height_ > 1 ? 2 * static_cast<std::size_t>(width_ - 1) * (height_ - 1) : 0;
  }
  std::size_t vertexCount() const { return pixelCount() + extraVertices_.size(); }
  std::size_t triangleCount() const { return innerTriangleCount() + extraTriangles_.size(); }
  const std::vector<ExtraVertex>& extraVertices() const { return extraVertices_; }

  // The rule's numbering, written here only: the inner triangle in half `half` (0: the one with
  // corner (col, row + 1), 1: with (col + 1, row)) of the square whose top-left centre is (col,
  // row), on a grid `width` centres wide. The planar index's grid path calls it a slot.
  static constexpr std::uint64_t innerTriangle(std::uint64_t width, std::uint64_t row, std::uint64_t col,
                                               std::uint32_t half) {
    return 2 * (row * (width - 1) + col) + half;
  }
  // The corners of the inner triangle in half `half` of the square whose top-left centre is (col,
  // row), in the order described above (what triangle() gives for its number).
  static constexpr std::array<std::uint32_t, 3> innerCorners(std::uint32_t width, std::uint32_t row, std::uint32_t col,
                                                             std::uint32_t half) {
    const std::uint32_t tl = row * width + col, tr = tl + 1, bl = tl + width, br = bl + 1;
    return half == 0 ? std::array<std::uint32_t, 3>{tl, bl, br} : std::array<std::uint32_t, 3>{tl, br, tr};
  }
  // The corners of triangle t, inner ones first, in the order described above.
  std::array<std::uint32_t, 3> triangle(std::size_t t) const;
  // The rule read backwards: the inner triangle whose corners are {a, b, c} in any order (the
  // planar index finds a grid in any mesh by it), or std::nullopt for none.
  std::optional<std::uint64_t> innerTriangleWith(std::uint32_t a, std::uint32_t b, std::uint32_t c) const;
  // Every triangle's corners, in order, three indices each (a Mesh's indices).
  std::vector<std::uint32_t> indices() const;
  // Adds to `mesh` the triangles from number `first` on whose three corners are valid
  // (valid(vertex) is true; a nodata pixel makes a hole), in the order above. The mesh's vertex
  // k must be this grid's vertex k. reverse: each triangle's corners in the opposite turn, for a
  // grid whose rows run up the screen (y growing with the row), so that its triangles too are
  // counter-clockwise seen from above.
  template <class Valid>
  void appendTriangles(Mesh& mesh, const Valid& valid, std::size_t first = 0, bool reverse = false) const {
    const auto add = [&](std::uint32_t a, std::uint32_t b, std::uint32_t c) {
      if (valid(a) && valid(b) && valid(c)) reverse ? mesh.addTriangle(a, c, b) : mesh.addTriangle(a, b, c);
    };
    const std::size_t inner = innerTriangleCount();
    mesh.indices.reserve(mesh.indices.size() + 3 * (triangleCount() - std::min(first, triangleCount())));
    const auto w = static_cast<std::uint32_t>(width_);
    for (std::size_t t = first - first % 2; t < inner; t += 2) {  // square by square, in row order
      const auto square = static_cast<std::uint32_t>(t / 2);
      const std::uint32_t tl = square / (w - 1) * w + square % (w - 1), tr = tl + 1, bl = tl + w, br = bl + 1;
      if (t >= first) add(tl, bl, br);
      add(tl, br, tr);
    }
    for (std::size_t t = std::max(first, inner); t < triangleCount(); ++t) {
      const auto& k = extraTriangles_[t - inner];
      add(k[0], k[1], k[2]);
    }
  }

  // The triangles that have pixel centre (row, col) as a corner, in increasing order; returns how many
  // (at most kMaxRing). closed: they go all the way round it (no edge of the surface there).
  static constexpr int kMaxRing = 8;
  int ring(int row, int col, std::uint32_t out[kMaxRing], bool& closed) const;

 private:
  std::uint32_t addExtra(double col, double row, std::uint32_t pixel, int pole = 0);

  int width_ = 0, height_ = 0;
  Closure closure_;
  std::vector<ExtraVertex> extraVertices_;
  std::vector<std::array<std::uint32_t, 3>> extraTriangles_;
  // The closure's triangles around each pixel centre on the raster's outermost rows and columns.
  std::unordered_map<std::uint32_t, std::vector<std::uint32_t>> extraRing_;
};

}  // namespace qota
