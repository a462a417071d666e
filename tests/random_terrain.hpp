// Random terrains for the oracle tests: a heightfield with holes cut into it, floating convex
// plates above and below it (overlaps and overhangs), and vertical walls (which must be left out).
#pragma once

#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include "qota/mesh.hpp"
#include "qota/synthetic.hpp"

namespace qota::test {

struct RandomTerrainSpec {
  int grid = 30;  // heightfield vertices per side
  double cell = 1.0;
  double holeFraction = 0.1;
  int plates = 60;  // floating convex polygons of 3 to 7 vertices
  int walls = 10;
  double offsetX = 0, offsetY = 0;  // shift, to test large coordinates
};

inline Mesh randomTerrain(const RandomTerrainSpec& spec, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0, 1);
  Heightfield field = fractalHeightfield(spec.grid, spec.grid, spec.cell, 0.2 * spec.grid * spec.cell, seed, 5);
  field.x0 = spec.offsetX;
  field.y0 = spec.offsetY;
  Mesh full = field.toMesh();
  Mesh m;
  m.vertices = full.vertices;
  for (std::size_t p = 0; p < full.polygonCount(); ++p) {
    if (unit(rng) < spec.holeFraction) continue;
    const auto t = full.polygon(p);
    m.addPolygon(t);
  }
  const double extent = (spec.grid - 1) * spec.cell;
  for (int i = 0; i < spec.plates; ++i) {
    // A convex polygon: corners at sorted random angles on an ellipse, on a random tilted plane.
    const int n = 3 + static_cast<int>(unit(rng) * 5);
    const double cx = spec.offsetX + unit(rng) * extent, cy = spec.offsetY + unit(rng) * extent;
    const double rx = (0.05 + 0.2 * unit(rng)) * extent, ry = (0.05 + 0.2 * unit(rng)) * extent;
    const double cz = (unit(rng) - 0.5) * 0.6 * extent;
    const double sx = (unit(rng) - 0.5), sy = (unit(rng) - 0.5);
    std::vector<double> ang(n);
    for (double& a : ang) a = unit(rng) * 2 * std::numbers::pi;
    std::sort(ang.begin(), ang.end());
    std::vector<std::uint32_t> corners;
    for (int k = 0; k < n; ++k) {
      const double x = cx + rx * std::cos(ang[k]), y = cy + ry * std::sin(ang[k]);
      corners.push_back(m.addVertex({x, y, cz + sx * (x - cx) + sy * (y - cy)}));
    }
    if (unit(rng) < 0.5) std::reverse(corners.begin(), corners.end());  // any winding
    m.addPolygon(corners);
  }
  for (int i = 0; i < spec.walls; ++i) {
    const double x = spec.offsetX + unit(rng) * extent, y = spec.offsetY + unit(rng) * extent;
    const std::uint32_t a = m.addVertex({x, y, -5}), b = m.addVertex({x + 2, y + 1, -5});
    const std::uint32_t c = m.addVertex({x + 2, y + 1, 5}), d = m.addVertex({x, y, 5});
    m.addPolygon({a, b, c, d});
  }
  return m;
}

}  // namespace qota::test
