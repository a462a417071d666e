#include "qota/raster_grid.hpp"

#include <algorithm>
#include <cassert>

namespace qota {

RasterGrid::RasterGrid(int width, int height, Closure closure) : width_(width), height_(height), closure_(closure) {
  const int w = width, h = height;
  // A seam needs three columns to close anything; caps close the rows round a seam only.
  if (w < 3) closure_.wrapsColumns = false;
  if (!closure_.wrapsColumns) closure_.northCap = closure_.southCap = false;
  const Closure& k = closure_;
  const auto pixel = [w](int r, int c) { return static_cast<std::uint32_t>(r * w + c); };

  // The border's vertices: edge rows above and below (lattice columns -1 .. w, or 0 .. w - 1
  // round a seam), edge columns left and right (rows 0 .. h - 1). edgeRow[c + 1], edgeCol[r].
  const bool top = k.border && !k.northCap, bottom = k.border && !k.southCap;
  const bool sides = k.border && !k.wrapsColumns;
  std::vector<std::uint32_t> topRow, bottomRow, leftCol, rightCol;
  const int cFirst = sides ? -1 : 0, cLast = sides ? w : w - 1;  // lattice columns
  const auto edgeRowVertices = [&](std::vector<std::uint32_t>& out, double row, int pixelRow) {
    out.assign(static_cast<std::size_t>(w) + 2, 0);
    for (int c = cFirst; c <= cLast; ++c) {
      const double col = c < 0 ? 0.0 : c >= w ? static_cast<double>(w) : c + 0.5;
      const int slot = c + 1;  // (column -1, the left border, at 0)
      out[static_cast<std::size_t>(slot)] = addExtra(col, row, pixel(pixelRow, c < 0 ? 0 : c >= w ? w - 1 : c));
    }
  };
  if (top) edgeRowVertices(topRow, 0.0, 0);
  if (bottom) edgeRowVertices(bottomRow, static_cast<double>(h), h - 1);
  if (sides) {
    leftCol.resize(static_cast<std::size_t>(h));
    rightCol.resize(static_cast<std::size_t>(h));
    for (int r = 0; r < h; ++r) leftCol[static_cast<std::size_t>(r)] = addExtra(0.0, r + 0.5, pixel(r, 0));
    for (int r = 0; r < h; ++r) {
      rightCol[static_cast<std::size_t>(r)] = addExtra(static_cast<double>(w), r + 0.5, pixel(r, w - 1));
    }
  }
  // The vertex at lattice (r, c): a pixel centre, or a border vertex.
  const auto vertex = [&](int r, int c) -> std::uint32_t {
    const int slot = c + 1;  // in a border row (column -1 at 0)
    if (r < 0) return topRow[static_cast<std::size_t>(slot)];
    if (r >= h) return bottomRow[static_cast<std::size_t>(slot)];
    if (c < 0) return leftCol[static_cast<std::size_t>(r)];
    if (c >= w) return rightCol[static_cast<std::size_t>(r)];
    return pixel(r, c);
  };

  // Every lattice square that is not an inner one, split as the inner ones (none without a
  // border or a seam: then every square is inner, and nothing here walks the cells).
  const int rFirst = top ? -1 : 0, rLast = bottom ? h : h - 1;
  const int squares = k.wrapsColumns ? w : cLast - cFirst;  // per lattice row
  for (int r = rFirst; r < rLast && (k.border || k.wrapsColumns); ++r) {
    for (int s = 0; s < squares; ++s) {
      const int c = cFirst + s, right = k.wrapsColumns ? (c + 1) % w : c + 1;
      if (r >= 0 && r + 1 < h && c >= 0 && c + 1 < w) continue;  // inner
      const std::uint32_t tl = vertex(r, c), tr = vertex(r, right), bl = vertex(r + 1, c), br = vertex(r + 1, right);
      extraTriangles_.push_back({tl, bl, br});
      extraTriangles_.push_back({tl, br, tr});
    }
  }
  // Caps: the pole fanned to its row, with the inner triangles' turn.
  if (k.northCap) {
    const std::uint32_t pole = addExtra(0.0, -0.5, 0, +1);
    for (int c = 0; c < w; ++c) extraTriangles_.push_back({pixel(0, c), pixel(0, (c + 1) % w), pole});
  }
  if (k.southCap) {
    const std::uint32_t pole = addExtra(0.0, h + 0.5, pixel(h - 1, 0), -1);
    for (int c = 0; c < w; ++c) extraTriangles_.push_back({pixel(h - 1, (c + 1) % w), pixel(h - 1, c), pole});
  }

  const std::size_t pixels = pixelCount(), inner = innerTriangleCount();
  for (std::size_t t = 0; t < extraTriangles_.size(); ++t) {
    for (const std::uint32_t v : extraTriangles_[t]) {
      if (v < pixels) extraRing_[v].push_back(static_cast<std::uint32_t>(inner + t));
    }
  }
}

std::uint32_t RasterGrid::addExtra(double col, double row, std::uint32_t pixel, int pole) {
  extraVertices_.push_back({col, row, pixel, pole});
  return static_cast<std::uint32_t>(pixelCount() + extraVertices_.size() - 1);
}

std::array<std::uint32_t, 3> RasterGrid::triangle(std::size_t t) const {
  const std::size_t inner = innerTriangleCount();
  if (t >= inner) return extraTriangles_[t - inner];
  const std::size_t square = t / 2, w = static_cast<std::size_t>(width_);
  return innerCorners(static_cast<std::uint32_t>(w), static_cast<std::uint32_t>(square / (w - 1)),
                      static_cast<std::uint32_t>(square % (w - 1)), static_cast<std::uint32_t>(t % 2));
}

std::optional<std::uint64_t> RasterGrid::innerTriangleWith(std::uint32_t a, std::uint32_t b, std::uint32_t c) const {
  std::array<std::uint32_t, 3> k{a, b, c};
  std::sort(k.begin(), k.end());
  const auto w = static_cast<std::uint64_t>(width_);
  const std::uint64_t x = k[0], col = w ? x % w : 0, row = w ? x / w : 0;
  // Both halves of the square (row, col) run along its diagonal TL = x to BR = x + w + 1.
  if (w < 2 || col + 1 >= w || row + 1 >= static_cast<std::uint64_t>(height_) || k[2] != x + w + 1) {
    return std::nullopt;
  }
  const std::uint64_t first = innerTriangle(w, row, col, 0);
  if (k[1] == x + w) return first;      // (TL, BL, BR)
  if (k[1] == x + 1) return first + 1;  // (TL, BR, TR)
  return std::nullopt;
}

std::vector<std::uint32_t> RasterGrid::indices() const {
  Mesh all;
  appendTriangles(all, [](std::uint32_t) { return true; });
  return std::move(all.indices);
}

int RasterGrid::ring(int row, int col, std::uint32_t out[kMaxRing], bool& closed) const {
  const int w = width_, h = height_;
  const auto first = [w](int r, int c) { return static_cast<std::uint32_t>(innerTriangle(w, r, c, 0)); };
  int n = 0;
  if (row > 0 && col > 0) out[n++] = first(row - 1, col - 1), out[n++] = first(row - 1, col - 1) + 1;
  if (row > 0 && col + 1 < w) out[n++] = first(row - 1, col);
  if (row + 1 < h && col > 0) out[n++] = first(row, col - 1) + 1;
  if (row + 1 < h && col + 1 < w) out[n++] = first(row, col), out[n++] = first(row, col) + 1;
  const bool edge = row == 0 || col == 0 || row + 1 == h || col + 1 == w;
  if (edge && !extraRing_.empty()) {
    const auto it = extraRing_.find(static_cast<std::uint32_t>(row * w + col));
    if (it != extraRing_.end()) {
      for (const std::uint32_t t : it->second) {
        assert(n < kMaxRing);
        if (n < kMaxRing) out[n++] = t;
      }
    }
  }
  const Closure& k = closure_;
  closed = (row > 0 || k.northCap || k.border) && (row + 1 < h || k.southCap || k.border) &&
           (col > 0 || k.wrapsColumns || k.border) && (col + 1 < w || k.wrapsColumns || k.border);
  return n;
}

std::uint64_t GridMesh::polygonCount() const {
  const auto w = static_cast<std::uint64_t>(std::max(width, 0)), h = static_cast<std::uint64_t>(std::max(height, 0));
  if (vertices.size() != w * h) return 0;
  const auto data = [&](std::uint64_t v) { return hasData(vertices[v]); };
  std::uint64_t n = 0;
  for (std::uint64_t r = 0; r + 1 < h; ++r) {
    for (std::uint64_t c = 0; c + 1 < w; ++c) {
      const std::uint64_t tl = r * w + c, tr = tl + 1, bl = tl + w, br = bl + 1;
      n += (data(tl) && data(bl) && data(br)) + (data(tl) && data(br) && data(tr));
    }
  }
  return n;
}

Mesh GridMesh::toMesh() const {
  Mesh mesh;
  mesh.vertices.assign(vertices.begin(), vertices.end());
  if (width >= 1 && height >= 1) {
    RasterGrid(width, height, {})
        .appendTriangles(
            mesh, [&](std::uint32_t v) { return hasData(vertices[v]); }, 0, reverse);
  }
  return mesh;
}

}  // namespace qota
