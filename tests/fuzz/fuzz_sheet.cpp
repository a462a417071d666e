// The one-sheet proof (lib/core/planar_sheet.hpp) against pairs: the bytes make a few triangles
// on a small lattice (vertices shared, or repeated at a lattice point under numbers of their
// own, some points moved off the lattice), each turned counter-clockwise; whenever the proof
// says one sheet, every pair of triangles is checked apart by the separating-axis rule on exact
// orientations, and a pair that overlaps stops the fuzzer (a wrong "one sheet" would make
// queries answer from the wrong triangle).
#include <cstdint>
#include <cstdlib>
#include <vector>

#include "planar_sheet.hpp"
#include "qota/predicates.hpp"

namespace {

using qota::Point2;
using qota::detail::TriangleCorners;

// Whether counter-clockwise triangles a and b have disjoint interiors: an edge line of one with
// every corner of the other on or outside it.
bool apart(const Point2 (&a)[3], const Point2 (&b)[3]) {
  const auto outside = [](const Point2(&p)[3], const Point2(&q)[3]) {
    for (int k = 0; k < 3; ++k) {
      bool all = true;
      for (int c = 0; c < 3 && all; ++c) all = qota::orient2dSign(p[k], p[(k + 1) % 3], q[c]) <= 0;
      if (all) return true;
    }
    return false;
  };
  return outside(a, b) || outside(b, a);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 2) return 0;
  std::size_t at = 0;
  const auto next = [&]() -> std::uint8_t { return at < size ? data[at++] : 0; };
  // A lattice of (n + 1)^2 points, some repeated under numbers of their own, some moved.
  const int n = 2 + next() % 5;
  std::vector<Point2> vertices;
  for (int r = 0; r <= n; ++r) {
    for (int c = 0; c <= n; ++c) vertices.push_back({static_cast<double>(c), static_cast<double>(r)});
  }
  const std::size_t lattice = vertices.size();
  for (int repeats = next() % 8; repeats > 0; --repeats) vertices.push_back(vertices[next() % lattice]);
  for (int moved = next() % 4; moved > 0; --moved) {
    Point2& p = vertices[next() % vertices.size()];
    p.u += (next() % 7 - 3) / 4.0, p.v += (next() % 7 - 3) / 4.0;
  }
  std::vector<TriangleCorners> triangles;
  while (at + 3 <= size && triangles.size() < 48) {
    std::uint32_t k[3];
    for (auto& c : k) c = next() % vertices.size();
    const int turn = qota::orient2dSign(vertices[k[0]], vertices[k[1]], vertices[k[2]]);
    if (turn == 0) continue;
    if (turn < 0) std::swap(k[1], k[2]);
    triangles.push_back({{k[0], k[1], k[2]}, static_cast<std::uint32_t>(triangles.size())});
  }
  if (!qota::detail::oneSheet(triangles, vertices)) return 0;
  for (std::size_t i = 0; i < triangles.size(); ++i) {
    for (std::size_t j = i + 1; j < triangles.size(); ++j) {
      Point2 a[3], b[3];
      for (int c = 0; c < 3; ++c) a[c] = vertices[triangles[i].corner[c]], b[c] = vertices[triangles[j].corner[c]];
      if (!apart(a, b)) std::abort();  // one sheet, yet two triangles overlap
    }
  }
  return 0;
}
