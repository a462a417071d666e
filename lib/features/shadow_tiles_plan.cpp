// ShadowTiles' plan (see qota/shadow_tiles.hpp): how far each tile's shadows reach, its halo,
// and the tile size a memory budget allows.
#include "qota/shadow_tiles.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <charconv>
#include <cmath>
#include <mutex>
#include <optional>
#include <sstream>

#include "qota/error.hpp"
#include "qota/memory_budget.hpp"
#include "qota/version.hpp"
#include "shadow_tiles_parts.hpp"

namespace qota {

using tiles::kDeg;
using tiles::Local;
using tiles::localAt;

namespace {

// Pixels of halo on every side beyond the reach (see the header): the meeting point's triangle,
// the tile pixels' rings, the window's own outer half pixel.
constexpr int kHaloPixels = 3;

// The pixel displacement (columns, rows) of a frame displacement d along the surface at l: d in
// the tangent plane, in the basis of one column and one row (least squares: they are not
// orthogonal on a sheared grid). Zero for a raster one pixel wide or high in that direction.
Eigen::Vector2d pixelsOf(const Local& l, const Eigen::Vector3d& d) {
  const Eigen::Vector3d t = d - d.dot(l.up) * l.up;
  Eigen::Matrix<double, 3, 2> j;
  j.col(0) = l.east - l.east.dot(l.up) * l.up;
  j.col(1) = l.south - l.south.dot(l.up) * l.up;
  const bool ce = j.col(0).squaredNorm() > 0, cs = j.col(1).squaredNorm() > 0;
  if (ce && cs) return (j.transpose() * j).ldlt().solve(j.transpose() * t);
  Eigen::Vector2d p = Eigen::Vector2d::Zero();
  if (ce) p.x() = j.col(0).dot(t) / j.col(0).squaredNorm();
  if (cs) p.y() = j.col(1).dot(t) / j.col(1).squaredNorm();
  return p;
}

// How much of a low light's extra memory a light takes: 0 at high suns (the cotangent of the
// altitude at most 1.5), 1 at low ones (at least 7.5: altitude 7.6 degrees and below), in between
// linearly. A low light's rays cross more triangles, and the strips hold each triangle once for
// every strip it spans.
double lowLightShare(const std::vector<Eigen::Vector3d>& lights) {
  double share = lights.empty() ? 1.0 : 0.0;
  for (const Eigen::Vector3d& l : lights) {
    const Eigen::Vector3d u = l.normalized();
    const double across = std::hypot(u.x(), u.y());
    const double cot = u.z() > 0 ? across / u.z() : INFINITY;
    share = std::max(share, std::clamp((cot - 1.5) / 6.0, 0.0, 1.0));
  }
  return share;
}

}  // namespace

std::uint64_t ShadowTiles::bytesPerWindowPixel() { return bytesPerWindowPixel({}); }

// How much more a light below the horizon takes (its rays' strips cross every triangle facing
// away, which is most of them): 0 at the horizon and above, 1 below it. Measured on the Rainier
// tile: already some 25 bytes a pixel more at 1.3 to 2.6 degrees below (the Sun before sunrise),
// up to 34 at 20 degrees below and beyond; so no ramp, the whole of it from the horizon down.
double belowShare(const std::vector<Eigen::Vector3d>& lights) {
  double share = lights.empty() ? 1.0 : 0.0;
  for (const Eigen::Vector3d& l : lights) share = std::max(share, l.z() < 0 ? 1.0 : 0.0);
  return share;
}

std::uint64_t ShadowTiles::bytesPerWindowPixel(const std::vector<Eigen::Vector3d>& lights) {
  // A window's frame at the mask's peak: vertices (24), validity and light (2), the triangles'
  // corners (24) and facing (2), the strips (24 a triangle entry, up to about 2 entries a pixel at
  // a low sun), the pixel order (8); before them, the heights read and filled. Measured on the
  // Rainier DEM (bench/shadow_memory.sh: single tiles of 16 to 1024 pixels from a state, peak RSS
  // less the process's, over the window's planned pixels): 92 to 101 bytes at altitudes 30 and
  // 60, 129 to 138 at 10, 142 to 144 at 5, 149 to 155 at 2; taken with a tenth more.
  // Below the horizon (a tile whose pixels still see the Sun): up to 40 more (measured: whole
  // rasters take up to 34 more at 20 degrees below and beyond).
  return static_cast<std::uint64_t>(std::ceil(105 + 66 * lowLightShare(lights) + 40 * belowShare(lights)));
}

std::uint64_t ShadowTiles::bytesPerWholePixel(const std::vector<Eigen::Vector3d>& lights) {
  // The whole raster in memory (loadDem's mesh, then the frame and the mask): measured on the
  // Rainier DEM 128 to 134 bytes a pixel at altitudes 30 and 60, 157 at 10, 171 at 5, 184 at 2
  // (peak RSS less the process's) when the frame's pixel positions were made whole before its
  // points; made a block at a time, about 115 at 45 and 175 at 2 (bench/shadow_memory.sh's
  // peaks, less the 62 MiB the process takes before); taken with a tenth more.
  // Below the horizon: up to 40 more (250 a pixel measured at 45 degrees below on Rainier).
  return static_cast<std::uint64_t>(std::ceil(140 + 66 * lowLightShare(lights) + 40 * belowShare(lights)));
}

std::array<int, 4> ShadowTiles::halo(const PixelWindow& tile, const std::vector<Eigen::Vector3d>& lights,
                                     double tileLowest) const {
  std::array<int, 4> out = reach(tile, lights, tileLowest);
  out[0] = std::min(out[0], tile.col), out[1] = std::min(out[1], basis_.raster.width - tile.col - tile.width);
  out[2] = std::min(out[2], tile.row), out[3] = std::min(out[3], basis_.raster.height - tile.row - tile.height);
  return out;
}

std::array<int, 4> ShadowTiles::reach(const PixelWindow& tile, const std::vector<Eigen::Vector3d>& lights,
                                      double tileLowest) const {
  std::array<int, 4> out{0, 0, 0, 0};
  const LocalFrame& f = basis_.shared;
  const Local here = localAt(basis_, tile.col + tile.width / 2, tile.row + tile.height / 2);
  // Above the tile centre's tangent plane (see the header).
  const double top = f.body.ellipsoid ? std::max(f.maxHeight, 0.0) : f.maxHeight;
  // On an ellipsoid (see the header): the ball of radius rM + top that holds all terrain, the
  // tile's pixels within d of its centre pixel across, and the slack below which every pixel's ray
  // enters the body.
  double d = 0, rM = 0, slack = 0;
  if (f.body.ellipsoid) {
    const int halfW = std::max(tile.width / 2, tile.width - tile.width / 2);
    const int halfH = std::max(tile.height / 2, tile.height - tile.height / 2);
    d = 1.1 * (here.east.norm() * halfW + here.south.norm() * halfH);
    rM = f.body.a * f.body.a / f.body.b;
    const double rMin = f.body.b * f.body.b / f.body.a;
    const double dip = std::acos(std::clamp((f.body.b + f.body.lowest) / (f.body.b + f.maxHeight), -1.0, 1.0));
    slack = 1.1 * d / rMin + dip + 0.02 * kDeg;
  }
  for (const Eigen::Vector3d& light0 : lights) {
    const Eigen::Vector3d light = light0.normalized();
    const double rise = light.dot(here.up);
    double reach = 0;  // along the ray
    if (!f.body.ellipsoid) {
      if (!(rise > 0)) continue;  // a flat frame's pixels are all in shadow: nothing to reach
      reach = std::max(0.0, top - tileLowest) / rise;
    } else {
      // Below every pixel's horizon by more than the dip: every ray enters the body, which shades
      // the pixel whatever the terrain (sunCanLight's argument, for the tile).
      if (rise <= -std::sin(slack)) continue;
      // The ray leaves the ball B(O - rM up, rM + top) after at most t = -q + sqrt(q^2 + k), for
      // q >= -d + (rM + z) rise (its pixel at height z in [lowest, top] above the tangent plane,
      // within d across) and k <= (rM + top)^2 - (rM + lowest)^2: t falls with q and grows with k.
      const double lo = std::min(tileLowest, top);
      const double q = -d + (rM + (rise >= 0 ? lo : top)) * rise;
      const double k = std::max(0.0, (top - lo) * (2 * rM + top + lo));
      reach = -q + std::sqrt(q * q + k);
      if (rise > 0) reach = std::min(reach, std::max(0.0, top - tileLowest) / rise);
    }
    Eigen::Vector2d p = pixelsOf(here, reach * light);
    if (f.body.ellipsoid) {
      const Local there = localAt(basis_, tile.col + tile.width / 2 + static_cast<int>(std::lround(p.x())),
                                  tile.row + tile.height / 2 + static_cast<int>(std::lround(p.y())));
      const Eigen::Vector2d q = pixelsOf(there, reach * light);
      p = 1.25 * p.cwiseAbs().cwiseMax(q.cwiseAbs()).cwiseProduct(p.cwiseSign());
    }
    const double cap = 4.0 * std::max(basis_.raster.width, basis_.raster.height);  // the raster is smaller
    const auto side = [&](double d) { return static_cast<int>(std::ceil(std::min(std::max(0.0, d), cap))); };
    out[0] = std::max(out[0], side(-p.x())), out[1] = std::max(out[1], side(p.x()));
    out[2] = std::max(out[2], side(-p.y())), out[3] = std::max(out[3], side(p.y()));
  }
  for (int& s : out) s += kHaloPixels;
  return out;
}

PixelWindow ShadowTiles::windowOf(const PixelWindow& tile, const std::array<int, 4>& h) const {
  return {tile.col - h[0], tile.row - h[2], tile.width + h[0] + h[1], tile.height + h[2] + h[3]};
}

int ShadowTiles::tileSideFor(std::uint64_t bytes, const std::vector<Eigen::Vector3d>& lights, int multiple) const {
  const int w = basis_.raster.width, h = basis_.raster.height;
  const std::uint64_t most = bytes / bytesPerWindowPixel(lights);
  // Whether tiles of `side` fit; a larger side never takes a smaller window.
  const auto fits = [&](int side) {
    const std::array<int, 4> o = haloFor(side, side, lights);
    const auto across = static_cast<std::uint64_t>(std::min(w, std::min(side, w) + o[0] + o[1]));
    const auto down = static_cast<std::uint64_t>(std::min(h, std::min(side, h) + o[2] + o[3]));
    return across * down <= most;
  };
  int lo = 0, hi = (std::max(w, h) + multiple - 1) / multiple;  // in multiples: lo fits (0: none), hi + 1 does not
  if (fits(hi * multiple)) return hi * multiple;
  while (hi - lo > 1) {
    const int mid = (lo + hi) / 2;
    (fits(mid * multiple) ? lo : hi) = mid;
  }
  return lo * multiple;
}

std::array<int, 4> ShadowTiles::haloFor(int tileWidth, int tileHeight,
                                        const std::vector<Eigen::Vector3d>& lights) const {
  return haloAtMost(tileWidth, tileHeight, lights, basis_.shared.minHeight);
}

std::uint64_t ShadowTiles::largestWindowPixels(const std::vector<PixelWindow>& tiles,
                                               const std::vector<Eigen::Vector3d>& lights) const {
  const LocalFrame& f = basis_.shared;
  const int rw = basis_.raster.width, rh = basis_.raster.height;
  int tw = 1, th = 1;
  for (const PixelWindow& t : tiles) tw = std::max(tw, t.width), th = std::max(th, t.height);
  // The halo falls as a tile's lowest pixel rises: tiles take the halo of the level at or below
  // their bound, one of kLevels between the raster's lowest and highest (a few dozen halos for any
  // number of tiles).
  constexpr int kLevels = 32;
  const double lo = std::isfinite(f.minHeight) ? f.minHeight : 0, hi = std::isfinite(f.maxHeight) ? f.maxHeight : lo;
  std::vector<std::optional<std::array<int, 4>>> halos(kLevels + 1);
  const double metres = f.metresPerUnit;
  std::uint64_t most = 0;
  for (const PixelWindow& t : tiles) {
    const auto [low, high] = blocks_.rangeOver(t);
    // The tile's lowest, at least (over the ellipsoid: with the geoid's least undulation).
    const double bound = (metres >= 0 ? low * metres : high * metres) + basis_.geoidLow;
    if (!std::isfinite(bound) && bound > 0) {  // no data: no window beyond the tile
      most = std::max<std::uint64_t>(most, t.pixelCount());
      continue;
    }
    const int level = hi > lo && std::isfinite(bound)
                          ? std::clamp(static_cast<int>(std::floor((bound - lo) / (hi - lo) * kLevels)), 0, kLevels)
                          : 0;
    if (!halos[static_cast<std::size_t>(level)]) {
      halos[static_cast<std::size_t>(level)] = haloAtMost(tw, th, lights, lo + (hi - lo) * level / kLevels);
    }
    const std::array<int, 4>& h = *halos[static_cast<std::size_t>(level)];
    const auto across = static_cast<std::uint64_t>(std::min(t.col + t.width + h[1], rw) - std::max(t.col - h[0], 0));
    const auto down = static_cast<std::uint64_t>(std::min(t.row + t.height + h[3], rh) - std::max(t.row - h[2], 0));
    most = std::max(most, across * down);
  }
  return most;
}

std::array<int, 4> ShadowTiles::haloAtMost(int tileWidth, int tileHeight, const std::vector<Eigen::Vector3d>& lights,
                                           double lowestHeight) const {
  const LocalFrame& f = basis_.shared;
  const int w = basis_.raster.width, h = basis_.raster.height;
  std::array<int, 4> out{0, 0, 0, 0};
  const int tw = std::min(tileWidth, w), th = std::min(tileHeight, h);
  // Unclipped by the raster's edges: the tile's halo as if the raster went on, at the centre and
  // the corners (on an ellipsoid the pixels' size changes across the raster).
  for (const auto& [c, r] :
       {std::pair{0.5, 0.5}, std::pair{0.0, 0.0}, std::pair{1.0, 0.0}, std::pair{0.0, 1.0}, std::pair{1.0, 1.0}}) {
    const PixelWindow tile{static_cast<int>(c * (w - tw)), static_cast<int>(r * (h - th)), tw, th};
    double lowest = lowestHeight;
    if (f.body.ellipsoid) {
      // The surface falls below the tangent plane at the tile's centre by at most d^2 / 2R at a
      // distance d (R: the ellipsoid's least radius of curvature, b^2 / a); d is at most half
      // the tile's sides together, measured at its corner (a tenth more for the change across).
      const Local l = localAt(basis_, tile.col, tile.row);
      const double d = 0.5 * std::max(tw, th) * (l.east.norm() + l.south.norm());
      lowest -= 1.1 * d * d / (2 * f.body.b * f.body.b / f.body.a);
    }
    const std::array<int, 4> one = reach(tile, lights, lowest);
    for (int k = 0; k < 4; ++k) out[k] = std::max(out[k], one[k]);
  }
  return out;
}

}  // namespace qota
