// Procedural terrains for tests, benchmarks and demos: fractal heightfields (octaves of value
// noise, the usual 1/f relief) on a regular grid, reproducible from a seed.
#pragma once

#include <cstdint>
#include <vector>

#include "qota/mesh.hpp"

namespace qota {

struct Heightfield {
  int nx = 0, ny = 0;     // vertices along x and y
  double cell = 1.0;      // spacing in x and y
  double x0 = 0, y0 = 0;  // position of vertex (0, 0)
  std::vector<double> z;  // row-major, z[j * nx + i]

  double at(int i, int j) const { return z[static_cast<std::size_t>(j) * nx + i]; }
  // Two triangles per cell, split along the diagonal from (i, j) to (i + 1, j + 1).
  Mesh toMesh() const;
  // The exact height of the triangulated surface at (x, y) by direct grid indexing (the same
  // diagonal as toMesh); false off the grid. The fastest possible answer for a regular grid.
  bool heightAt(double x, double y, double& h) const;
};

// An nx x ny fractal heightfield with spacing `cell`, relief amplitude about `amplitude`.
Heightfield fractalHeightfield(int nx, int ny, double cell, double amplitude, std::uint64_t seed, int octaves = 8);

}  // namespace qota
