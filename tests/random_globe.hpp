// Random closed meshes for the curved mappings: bumpy icospheres (planets, ellipsoids) and bumpy
// tubes (stations), reproducible from a seed.
#pragma once

#include <Eigen/Geometry>
#include <cmath>
#include <map>
#include <random>
#include <utility>
#include <vector>

#include "qota/mesh.hpp"

namespace qota::test {

// Unit icosphere subdivided `level` times (20 * 4^level triangles), rotated by a random rotation
// when `rotate` (so seams and poles fall anywhere), else with one vertex snapped exactly onto
// each pole (pole fans).
inline Mesh unitIcosphere(int level, std::mt19937_64& rng, bool rotate) {
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  Mesh m;
  for (const Eigen::Vector3d& v :
       {Eigen::Vector3d(-1, t, 0), Eigen::Vector3d(1, t, 0), Eigen::Vector3d(-1, -t, 0), Eigen::Vector3d(1, -t, 0),
        Eigen::Vector3d(0, -1, t), Eigen::Vector3d(0, 1, t), Eigen::Vector3d(0, -1, -t), Eigen::Vector3d(0, 1, -t),
        Eigen::Vector3d(t, 0, -1), Eigen::Vector3d(t, 0, 1), Eigen::Vector3d(-t, 0, -1), Eigen::Vector3d(-t, 0, 1)}) {
    m.addVertex(v.normalized());
  }
  const int faces[20][3] = {{0, 11, 5},  {0, 5, 1},  {0, 1, 7},  {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                            {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
                            {3, 8, 9},   {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
  for (const auto& f : faces) m.addTriangle(f[0], f[1], f[2]);
  for (int l = 0; l < level; ++l) {
    std::map<std::pair<std::uint32_t, std::uint32_t>, std::uint32_t> mid;
    auto midpoint = [&](std::uint32_t a, std::uint32_t b) {
      const auto key = std::minmax(a, b);
      auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      const std::uint32_t i = m.addVertex((m.vertices[a] + m.vertices[b]).normalized());
      mid.emplace(key, i);
      return i;
    };
    std::vector<std::uint32_t> indices;
    indices.reserve(m.indices.size() * 4);
    const std::size_t faces = m.polygonCount();
    for (std::size_t f = 0; f < faces; ++f) {
      const std::uint32_t a = m.indices[3 * f], b = m.indices[3 * f + 1], c = m.indices[3 * f + 2];
      const std::uint32_t ab = midpoint(a, b), bc = midpoint(b, c), ca = midpoint(c, a);
      indices.insert(indices.end(), {a, ab, ca, b, bc, ab, c, ca, bc, ab, bc, ca});
    }
    m.indices = std::move(indices);
  }
  if (rotate) {
    std::normal_distribution<double> g;
    const Eigen::Quaterniond q = Eigen::Quaterniond(g(rng), g(rng), g(rng), g(rng)).normalized();
    for (auto& v : m.vertices) v = q * v;
  } else {
    // Vertex 5 is (0, 1, t)/|..|; rotate it onto +z, its opposite (vertex 6) lands on -z.
    const Eigen::Quaterniond q = Eigen::Quaterniond::FromTwoVectors(m.vertices[5], Eigen::Vector3d(0, 0, 1));
    for (auto& v : m.vertices) v = q * v;
    m.vertices[5] = Eigen::Vector3d(0, 0, 1);
    m.vertices[6] = Eigen::Vector3d(0, 0, -1);
  }
  return m;
}

// A tube around the z axis: nx columns (angle wraps) by ny rings over [-length/2, length/2],
// radius * (1 + bump * uniform(-1, 1)) per vertex, each cell split along a random diagonal.
inline Mesh bumpyTube(int nx, int ny, double radius, double length, double bump, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> unit(-1, 1);
  Mesh m;
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) {
      const double a = 2 * M_PI * i / nx, r = radius * (1 + bump * unit(rng));
      m.addVertex({r * std::cos(a), r * std::sin(a), -0.5 * length + length * j / (ny - 1)});
    }
  }
  for (int j = 0; j + 1 < ny; ++j) {
    for (int i = 0; i < nx; ++i) {
      const auto a = static_cast<std::uint32_t>(j * nx + i);
      const auto b = static_cast<std::uint32_t>(j * nx + (i + 1) % nx);
      const std::uint32_t c = a + nx, d = b + nx;
      if (unit(rng) > 0) {
        m.addTriangle(a, c, d), m.addTriangle(a, d, b);
      } else {
        m.addTriangle(a, c, b), m.addTriangle(b, c, d);
      }
    }
  }
  return m;
}

}  // namespace qota::test
