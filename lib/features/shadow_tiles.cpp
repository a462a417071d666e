// Shadows of a raster tile by tile (see qota/shadow_tiles.hpp for why each tile is exact): the
// pass over the heights, each tile's window and frame, its mask and its hours of sunlight.
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

std::string pixels(const PixelWindow& w) {
  return "(" + std::to_string(w.col) + ", " + std::to_string(w.row) + ") + " + std::to_string(w.width) + " x " +
         std::to_string(w.height);
}

// Whether the fill over `fill` (levels from fillVoids) is the whole raster's at every void pixel of
// `region` (inside `fill`): each has twice its level of room to the fill's sides inside the raster.
bool filledAsWhole(const PixelWindow& fill, const std::vector<std::uint8_t>& valid,
                   const std::vector<std::uint32_t>& levels, const PixelWindow& region, int rasterWidth,
                   int rasterHeight) {
  constexpr std::int64_t kFree = std::int64_t{1} << 40;  // no side there: the raster's edge
  for (int r = region.row; r < region.row + region.height; ++r) {
    for (int c = region.col; c < region.col + region.width; ++c) {
      const std::size_t i = static_cast<std::size_t>(r - fill.row) * fill.width + (c - fill.col);
      if (valid[i]) continue;
      const std::int64_t room =
          std::min({fill.col > 0 ? c - fill.col : kFree,
                    fill.col + fill.width < rasterWidth ? fill.col + fill.width - 1 - c : kFree,
                    fill.row > 0 ? r - fill.row : kFree,
                    fill.row + fill.height < rasterHeight ? fill.row + fill.height - 1 - r : kFree});
      if (room < kFree && (levels[i] == kNeverFilled || room < 2 * static_cast<std::int64_t>(levels[i]))) return false;
    }
  }
  return true;
}

// The part `inner` of a window's pixels.
template <class T>
std::vector<T> crop(const std::vector<T>& all, const PixelWindow& outer, const PixelWindow& inner) {
  std::vector<T> out(inner.pixelCount());
  for (int r = 0; r < inner.height; ++r) {
    const std::size_t from =
        static_cast<std::size_t>(r + inner.row - outer.row) * outer.width + (inner.col - outer.col);
    std::copy_n(all.begin() + static_cast<std::ptrdiff_t>(from), inner.width,
                out.begin() + static_cast<std::ptrdiff_t>(r) * inner.width);
  }
  return out;
}

std::vector<Light> tileMask(const LocalFrame& frame, const PixelWindow& tile, const Eigen::Vector3d& light,
                            const IndexOptions& options, unsigned threads, ShadowSearch search) {
  if (frame.pixelCount() == 0) return std::vector<Light>(tile.pixelCount(), Light::NoData);
  const PixelWindow& window = frame.window;
  const PixelWindow inside{tile.col - window.col, tile.row - window.row, tile.width, tile.height};
  return crop(shadowMask(frame, light, options, {}, threads, search, inside),
              PixelWindow{0, 0, window.width, window.height}, inside);
}

}  // namespace

ShadowTiles::ShadowTiles(const std::string& path, const DemOptions& demOptions, const FrameOptions& frameOptions,
                         const Progress& progress, std::uint64_t bytes)
    : source_(std::make_unique<Source>()) {
  source_->windows = std::make_unique<DemWindows>(path, demOptions);
  const DemWindows* windows = source_->windows.get();
  source_->reader = [windows](const PixelWindow& w, std::vector<double>& out) {
    windows->read(w.col, w.row, w.width, w.height, out);
  };
  basis_ = frameBasis(windows->dem(), frameOptions);
  passOverHeights(progress, bytes);
}

ShadowTiles::ShadowTiles(const DemTerrain& description, HeightReader read, const FrameOptions& frameOptions,
                         const Progress& progress, std::uint64_t bytes)
    : source_(std::make_unique<Source>()) {
  source_->reader = std::move(read);
  basis_ = frameBasis(description, frameOptions);
  passOverHeights(progress, bytes);
}

ShadowTiles::ShadowTiles(ShadowTiles&&) noexcept = default;

ShadowTiles& ShadowTiles::operator=(ShadowTiles&&) noexcept = default;

void ShadowTiles::passOverHeights(const Progress& progress, std::uint64_t bytes) {
  const std::string& path = basis_.raster.path;
  const int w = basis_.raster.width, h = basis_.raster.height;
  const RasterGrid::Closure& closure = basis_.closure;
  if (closure.wrapsColumns || closure.northCap || closure.southCap) {
    throw Error(path + ": the raster is closed round the globe, so it is shadowed whole, not by tiles");
  }
  // The height range: one pass by rows, a few million pixels at a time.
  double lo = INFINITY, hi = -INFINITY;
  const std::uint64_t pixelsAtOnce = std::max<std::uint64_t>(1, (bytes ? bytes : kPassBytes) / kPassBytesPerPixel);
  const int rowsAtOnce = static_cast<int>(std::clamp<std::uint64_t>(pixelsAtOnce / std::max(1, w), 1, h));
  std::vector<double> z;
  std::vector<std::uint8_t> valid;
  blocks_ = HeightBlocks(w, h);
  for (int r = 0; r < h; r += rowsAtOnce) {
    const PixelWindow rows{0, r, w, std::min(rowsAtOnce, h - r)};
    source_->read(rows, z, nullptr, path);
    blocks_.addRows(rows.row, rows.height, z);
    heightsInMetres(basis_, rows, z, valid);
    for (std::size_t i = 0; i < z.size(); ++i) {
      if (valid[i]) lo = std::min(lo, z[i]), hi = std::max(hi, z[i]), ++validPixels_;
    }
    if (progress && !progress(static_cast<double>(r + rows.height) / h, "reading the height range")) {
      throw Error("shadow computation cancelled");
    }
  }
  // The centre square, for the pixel size and the triangles' turn (its fill, in a void, read
  // within a bound: a void half the raster wide is refused rather than read whole).
  const PixelWindow centre{std::max(0, (w - 1) / 2), std::max(0, (h - 1) / 2), std::min(2, w), std::min(2, h)};
  readFilled(centre, z, valid, 512ull << 20);
  const LocalFrame centreFrame = windowFrame(basis_, centre, std::move(z), std::move(valid));
  completeBasis(basis_, lo, hi, centreFrame);

  // The horizon slack (LocalFrame::horizonSlack) from the rim's pixels: the tilt between the
  // centre's up and a pixel's grows with the angle between them, largest on the rim of a raster
  // not reaching round the globe. Up from the pixels at height 0 and at the highest pixel's height
  // (the up of the frame's formula moves a little with the height), and a hundredth of a degree
  // more for the in-between.
  if (basis_.shared.body.ellipsoid) {
    double cosTilt = 1;
    const LocalFrame& f = basis_.shared;
    const Eigen::RowVector3d upRow = f.body.rotation.row(2);
    for (const PixelWindow& rim :
         {PixelWindow{0, 0, w, 1}, PixelWindow{0, h - 1, w, 1}, PixelWindow{0, 0, 1, h}, PixelWindow{w - 1, 0, 1, h}}) {
      for (const double height : {0.0, f.maxHeight, f.minHeight}) {
        const LocalFrame edge = windowFrame(basis_, rim, std::vector<double>(rim.pixelCount(), height),
                                            std::vector<std::uint8_t>(rim.pixelCount(), 1));
        for (std::size_t i = 0; i < rim.pixelCount(); ++i) {
          const Eigen::Vector3d x = f.body.rotation.transpose() * edge.mesh.vertices[i] + f.body.origin;
          const Eigen::Vector3d g(x.x() / (f.body.a * f.body.a), x.y() / (f.body.a * f.body.a),
                                  x.z() / (f.body.b * f.body.b));
          cosTilt = std::min(cosTilt, upRow.dot(g) / g.norm());
        }
      }
    }
    const double tilt = std::acos(std::clamp(cosTilt, -1.0, 1.0));
    const double dip = std::acos(std::clamp((f.body.b + f.body.lowest) / (f.body.b + f.maxHeight), -1.0, 1.0));
    slack_ = (tilt + dip) / kDeg + 0.02;
  }
}

ShadowTiles::~ShadowTiles() = default;

void ShadowTiles::readFilled(const PixelWindow& window, std::vector<double>& heights, std::vector<std::uint8_t>& valid,
                             std::uint64_t bytes) const {
  if (!source_) throw Error(basis_.raster.path + ": tiles restored from a state read no heights; give them");
  const int rw = basis_.raster.width, rh = basis_.raster.height;
  std::vector<double> z;
  std::vector<std::uint8_t> ok;
  std::vector<std::uint32_t> levels;
  for (int margin = 16;; margin *= 2) {
    const PixelWindow fill{std::max(0, window.col - margin), std::max(0, window.row - margin),
                           std::min(rw, window.col + window.width + margin) - std::max(0, window.col - margin),
                           std::min(rh, window.row + window.height + margin) - std::max(0, window.row - margin)};
    if (bytes && fill.pixelCount() * 16 > bytes) {
      throw Error(basis_.raster.path + ": a void (pixels without data) around pixels " + pixels(window) +
                  " is too wide to fill the same way as over the whole raster within the memory allowed (" +
                  memory::gib(bytes) + "); fill it first (gdal_fillnodata) or allow more memory");
    }
    source_->read(fill, z, &blocks_, basis_.raster.path);
    heightsInMetres(basis_, fill, z, ok);
    fillVoids(z, fill.width, fill.height, &levels);
    if (!filledAsWhole(fill, ok, levels, window, rw, rh)) continue;
    heights = crop(z, fill, window);
    valid = crop(ok, fill, window);
    return;
  }
}

double ShadowTiles::lowestOf(const PixelWindow& tile, std::vector<double> z,
                             const std::vector<std::uint8_t>& valid) const {
  if (std::find(valid.begin(), valid.end(), 1) == valid.end()) return INFINITY;
  const Local here = localAt(basis_, tile.col + tile.width / 2, tile.row + tile.height / 2);
  fillVoids(z, tile.width, tile.height);  // positions only: the valid pixels' do not depend on it
  const LocalFrame alone = windowFrame(basis_, tile, std::move(z), valid);
  double lowest = INFINITY;
  for (std::size_t i = 0; i < tile.pixelCount(); ++i) {
    if (valid[i]) lowest = std::min(lowest, (alone.mesh.vertices[i] - here.origin).dot(here.up));
  }
  return lowest;
}

double ShadowTiles::lowestIn(const PixelWindow& tile) const {
  if (!source_) throw Error(basis_.raster.path + ": tiles restored from a state read no heights; give them");
  std::vector<double> z;
  std::vector<std::uint8_t> valid;
  source_->read(tile, z, &blocks_, basis_.raster.path);
  heightsInMetres(basis_, tile, z, valid);
  return lowestOf(tile, std::move(z), valid);
}

LocalFrame ShadowTiles::frameOver(const PixelWindow& tile, const PixelWindow& window, std::uint64_t bytes,
                                  const std::vector<Eigen::Vector3d>& lights) const {
  if (bytes && window.pixelCount() * bytesPerWindowPixel(lights) > bytes) {
    throw Error(basis_.raster.path + ": pixels " + pixels(tile) + " need a window of " + pixels(window) + " (" +
                memory::gib(window.pixelCount() * bytesPerWindowPixel(lights)) +
                ") to hold every triangle that can shade them, over the " + memory::gib(bytes) +
                " allowed; use smaller tiles or allow more memory");
  }
  std::vector<double> z;
  std::vector<std::uint8_t> valid;
  readFilled(window, z, valid, bytes);
  return windowFrame(basis_, window, std::move(z), std::move(valid));
}

LocalFrame ShadowTiles::windowOfTile(const PixelWindow& tile, const std::vector<Eigen::Vector3d>& lights,
                                     std::uint64_t bytes, PixelWindow& window) const {
  const double lowest = lowestIn(tile);
  if (!std::isfinite(lowest)) {  // no data: nothing to test
    window = tile;
    return {};
  }
  window = windowOf(tile, halo(tile, lights, lowest));
  return frameOver(tile, window, bytes, lights);
}

LocalFrame ShadowTiles::givenWindow(const PixelWindow& given, std::vector<double> z, const PixelWindow& tile,
                                    const std::vector<Eigen::Vector3d>& lights) const {
  const int rw = basis_.raster.width, rh = basis_.raster.height;
  const auto inside = [](const PixelWindow& in, const PixelWindow& out) {
    return in.col >= out.col && in.row >= out.row && in.col + in.width <= out.col + out.width &&
           in.row + in.height <= out.row + out.height;
  };
  if (given.col < 0 || given.row < 0 || given.col + given.width > rw || given.row + given.height > rh ||
      z.size() != given.pixelCount() || !inside(tile, given) || tile.width < 1 || tile.height < 1) {
    throw Error(basis_.raster.path + ": heights of pixels " + pixels(given) + " (" + std::to_string(z.size()) +
                " given) for the tile " + pixels(tile) + ": not on the raster or not around the tile");
  }
  if (!blocks_.aligned(given)) {
    throw Error(basis_.raster.path + ": heights of pixels " + pixels(given) + " given: not whole hash blocks of " +
                std::to_string(blocks_.side()) + " pixels, so they cannot be checked (give checkableWindow's " +
                pixels(blocks_.alignedOut(given)) + ")");
  }
  blocks_.check(given, z, basis_.raster.path);
  std::vector<std::uint8_t> valid;
  heightsInMetres(basis_, given, z, valid);
  const double lowest = lowestOf(tile, crop(z, given, tile), crop(valid, given, tile));
  if (!std::isfinite(lowest)) return {};
  const PixelWindow window = windowOf(tile, halo(tile, lights, lowest));
  if (!inside(window, given)) {
    throw Error(basis_.raster.path + ": the tile " + pixels(tile) + " needs the pixels " + pixels(window) +
                " around it (its halo), but only " + pixels(given) + " are given; give a larger overlap (haloFor)");
  }
  std::vector<std::uint32_t> levels;
  fillVoids(z, given.width, given.height, &levels);
  if (!filledAsWhole(given, valid, levels, window, rw, rh)) {
    throw Error(basis_.raster.path + ": a void (pixels without data) near the tile " + pixels(tile) +
                " is too wide to fill the same way as over the whole raster from the pixels " + pixels(given) +
                "; give a larger overlap or fill the voids first (gdal_fillnodata)");
  }
  return windowFrame(basis_, window, crop(z, given, window), crop(valid, given, window));
}

std::vector<Light> ShadowTiles::mask(const PixelWindow& tile, const Eigen::Vector3d& light, const IndexOptions& options,
                                     unsigned threads, ShadowSearch search, std::uint64_t bytes) const {
  PixelWindow window;
  return tileMask(windowOfTile(tile, {light}, bytes, window), tile, light, options, threads, search);
}

std::vector<Light> ShadowTiles::maskFromHeights(const PixelWindow& window, std::vector<double> heights,
                                                const PixelWindow& tile, const Eigen::Vector3d& light,
                                                const IndexOptions& options, unsigned threads,
                                                ShadowSearch search) const {
  return tileMask(givenWindow(window, std::move(heights), tile, {light}), tile, light, options, threads, search);
}

std::vector<Eigen::Vector3d> ShadowTiles::sunlightSteps(double startJulianDay, double endJulianDay, double stepHours,
                                                        double slack) const {
  std::vector<Eigen::Vector3d> out;
  const LocalFrame& f = basis_.shared;
  for (const SunlightStep& step : qota::sunlightSteps(startJulianDay, endJulianDay, stepHours)) {
    const SunPosition sun = sunOverFrame(f, step.middleJulianDay, basis_.raster.path);
    if (sunCanLight(f, sun, slack)) out.push_back(f.towardSun(sun));
  }
  return out;
}

SunlightHours ShadowTiles::tileHours(const LocalFrame& frame, const PixelWindow& tile, double startJulianDay,
                                     double endJulianDay, double stepHours, const IndexOptions& options,
                                     ShadowSearch search, unsigned threads) const {
  if (frame.pixelCount() == 0) {  // no data: no hours (sunlightHours's zeros), its steps counted alike
    SunlightHours none;
    none.elapsedHours = (endJulianDay - startJulianDay) * 24.0;
    none.steps = static_cast<int>(qota::sunlightSteps(startJulianDay, endJulianDay, stepHours).size());
    none.hours.assign(tile.pixelCount(), 0.0);
    none.valid.assign(tile.pixelCount(), 0);
    return none;
  }
  // Every step the window's own sunlightHours computes is among the halo's lights when its slack
  // is within the bound they were chosen with.
  if (frame.body.ellipsoid && frame.horizonSlack() > slack_ + 1e-9) {
    throw Error(basis_.raster.path + ": the horizon slack of pixels " + pixels(frame.window) +
                " exceeds the raster's bound");
  }
  const PixelWindow& window = frame.window;
  const PixelWindow inside{tile.col - window.col, tile.row - window.row, tile.width, tile.height};
  SunlightHours all = sunlightHours(frame, basis_.raster.path, startJulianDay, endJulianDay, stepHours, options, {},
                                    search, inside, threads);
  all.hours = crop(all.hours, PixelWindow{0, 0, window.width, window.height}, inside);
  all.valid = crop(frame.valid, PixelWindow{0, 0, window.width, window.height}, inside);
  return all;
}

SunlightHours ShadowTiles::hours(const PixelWindow& tile, double startJulianDay, double endJulianDay, double stepHours,
                                 const IndexOptions& options, ShadowSearch search, std::uint64_t bytes,
                                 unsigned threads) const {
  const double lowest = lowestIn(tile);
  if (!std::isfinite(lowest))
    return tileHours(LocalFrame{}, tile, startJulianDay, endJulianDay, stepHours, options, search, threads);
  // A low sun's halo is long, a high sun's short: a window for every light of the day would be a
  // sunrise's for the noon steps too. So the steps whose own window is at most twice the smallest
  // share one window, the others (the low suns) another, loaded as the steps come, in order; the
  // lit pixels are summed in step order, as sunlightHours sums them.
  const std::vector<SunlightStep> steps = qota::sunlightSteps(startJulianDay, endJulianDay, stepHours);
  const LocalFrame& f = basis_.shared;
  std::vector<int> group(steps.size(), -1);  // -1: night over the whole raster (skipped there too)
  std::vector<Eigen::Vector3d> stepLight(steps.size());
  std::vector<std::uint64_t> windowPixels(steps.size(), 0);
  std::uint64_t smallest = ~std::uint64_t{0};
  for (std::size_t k = 0; k < steps.size(); ++k) {
    const SunPosition sun = sunOverFrame(f, steps[k].middleJulianDay, basis_.raster.path);
    if (!sunCanLight(f, sun, slack_)) continue;
    stepLight[k] = f.towardSun(sun);
    windowPixels[k] = windowOf(tile, halo(tile, {stepLight[k]}, lowest)).pixelCount();
    smallest = std::min(smallest, windowPixels[k]);
    group[k] = 0;
  }
  std::vector<Eigen::Vector3d> groupLights[2];
  for (std::size_t k = 0; k < steps.size(); ++k) {
    if (group[k] < 0) continue;
    group[k] = windowPixels[k] <= 2 * smallest ? 0 : 1;
    groupLights[group[k]].push_back(stepLight[k]);
  }
  SunlightHours out;
  out.elapsedHours = (endJulianDay - startJulianDay) * 24.0;
  out.steps = static_cast<int>(steps.size());
  out.hours.assign(tile.pixelCount(), 0.0);
  LocalFrame frame;
  int loaded = -1;
  double frameSlack = 0;
  PixelWindow inside;
  const auto load = [&](int g) {
    frame = frameOver(tile, windowOf(tile, halo(tile, groupLights[g], lowest)), bytes, groupLights[g]);
    // Every step the window computes is among its lights when its slack is within the bound
    // they were chosen with (sunlightHours's skip, for the window).
    if (frame.body.ellipsoid && frame.horizonSlack() > slack_ + 1e-9) {
      throw Error(basis_.raster.path + ": the horizon slack of pixels " + pixels(frame.window) +
                  " exceeds the raster's bound");
    }
    frameSlack = frame.horizonSlack();
    inside = PixelWindow{tile.col - frame.window.col, tile.row - frame.window.row, tile.width, tile.height};
    if (out.valid.empty())
      out.valid = crop(frame.valid, PixelWindow{0, 0, frame.window.width, frame.window.height}, inside);
    loaded = g;
  };
  for (std::size_t k = 0; k < steps.size(); ++k) {
    if (group[k] < 0) continue;
    if (group[k] != loaded) load(group[k]);
    const SunPosition sun = sunOverFrame(frame, steps[k].middleJulianDay, basis_.raster.path);
    if (!sunCanLight(frame, sun, frameSlack)) continue;  // night over the window
    const std::vector<Light> mask = shadowMask(frame, frame.towardSun(sun), options, {}, threads, search, inside);
    const int ww = frame.window.width;
    for (int r = 0; r < tile.height; ++r) {
      for (int c = 0; c < tile.width; ++c) {
        const std::size_t i = static_cast<std::size_t>(inside.row + r) * ww + static_cast<std::size_t>(inside.col + c);
        if (mask[i] == Light::Lit) out.hours[static_cast<std::size_t>(r) * tile.width + c] += steps[k].hours;
      }
    }
  }
  if (out.valid.empty()) load(0);  // no step lit: the validity from a window for none
  return out;
}

SunlightHours ShadowTiles::hoursFromHeights(const PixelWindow& window, std::vector<double> heights,
                                            const PixelWindow& tile, double startJulianDay, double endJulianDay,
                                            double stepHours, const std::vector<Eigen::Vector3d>& lights,
                                            const IndexOptions& options, ShadowSearch search, unsigned threads) const {
  return tileHours(givenWindow(window, std::move(heights), tile, lights), tile, startJulianDay, endJulianDay, stepHours,
                   options, search, threads);
}

}  // namespace qota
