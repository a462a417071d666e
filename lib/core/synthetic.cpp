#include "qota/synthetic.hpp"

#include "qota/raster_grid.hpp"

#include <cmath>

namespace qota {
namespace {

// A well-mixed 64-bit hash (splitmix64's finaliser) of a lattice point and seed, mapped to [-1, 1].
double lattice(std::int64_t i, std::int64_t j, std::uint64_t seed) {
  std::uint64_t x = seed ^ (static_cast<std::uint64_t>(i) * 0x9E3779B97F4A7C15ull) ^
                    (static_cast<std::uint64_t>(j) * 0xC2B2AE3D27D4EB4Full);
  x ^= x >> 30;
  x *= 0xBF58476D1CE4E5B9ull;
  x ^= x >> 27;
  x *= 0x94D049BB133111EBull;
  x ^= x >> 31;
  return static_cast<double>(x >> 11) * 0x1p-52 - 1.0;
}

double smooth(double t) { return t * t * (3 - 2 * t); }

double valueNoise(double x, double y, std::uint64_t seed) {
  const double fx = std::floor(x), fy = std::floor(y);
  const auto i = static_cast<std::int64_t>(fx), j = static_cast<std::int64_t>(fy);
  const double tx = smooth(x - fx), ty = smooth(y - fy);
  const double a = lattice(i, j, seed), b = lattice(i + 1, j, seed);
  const double c = lattice(i, j + 1, seed), d = lattice(i + 1, j + 1, seed);
  return (a + (b - a) * tx) * (1 - ty) + (c + (d - c) * tx) * ty;
}

}  // namespace

Heightfield fractalHeightfield(int nx, int ny, double cell, double amplitude, std::uint64_t seed, int octaves) {
  Heightfield f;
  f.nx = nx;
  f.ny = ny;
  f.cell = cell;
  f.z.resize(static_cast<std::size_t>(nx) * ny);
  // The coarsest octave spans about a quarter of the grid; each finer one halves wavelength and
  // amplitude.
  const double base = std::max(nx, ny) / 4.0;
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) {
      double h = 0, amp = amplitude, freq = 1.0 / base;
      for (int o = 0; o < octaves; ++o) {
        h += amp * valueNoise(i * freq, j * freq, seed + static_cast<std::uint64_t>(o));
        amp *= 0.5;
        freq *= 2.0;
      }
      f.z[static_cast<std::size_t>(j) * nx + i] = h;
    }
  }
  return f;
}

Mesh Heightfield::toMesh() const {
  Mesh m;
  m.vertices.reserve(z.size());
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) m.addVertex({x0 + i * cell, y0 + j * cell, at(i, j)});
  }
  // The raster rule (raster_grid.hpp) with rows running up y: (i, j) (i+1, j+1) (i, j+1), then
  // (i, j) (i+1, j) (i+1, j+1), counter-clockwise seen from above.
  RasterGrid(nx, ny, {})
      .appendTriangles(
          m, [](std::uint32_t) { return true; }, 0, /*reverse=*/true);
  return m;
}

bool Heightfield::heightAt(double x, double y, double& h) const {
  const double gx = (x - x0) / cell, gy = (y - y0) / cell;
  if (!(gx >= 0 && gy >= 0 && gx <= nx - 1 && gy <= ny - 1)) return false;
  int i = static_cast<int>(gx), j = static_cast<int>(gy);
  i = i < nx - 1 ? i : nx - 2;
  j = j < ny - 1 ? j : ny - 2;
  const double fx = gx - i, fy = gy - j;
  const double z00 = at(i, j), z10 = at(i + 1, j), z01 = at(i, j + 1), z11 = at(i + 1, j + 1);
  // Above the diagonal (fy > fx): triangle (00, 11, 01); else (00, 10, 11).
  h = fy > fx ? z00 + fx * (z11 - z01) + fy * (z01 - z00) : z00 + fx * (z10 - z00) + fy * (z11 - z10);
  return true;
}

}  // namespace qota
