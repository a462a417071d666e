#include "qota/raster_sampler.hpp"

#include <algorithm>
#include <exception>
#include <mutex>
#include <thread>
#include <utility>
#include <cmath>
#include <limits>

#include "qota/batch.hpp"
#include "qota/error.hpp"
#include "qota/raster_grid.hpp"

namespace qota {

RasterSampler::RasterSampler(const std::string& path, const Options& options)
    : options_(options),
      windows_(path, DemOptions{.band = options.band, .lonLatAsCartesian = options.lonLatAsCartesian}) {
  if (options_.tileSize < 1) throw Error("RasterSampler: tileSize must be at least 1");
  const DemTerrain& d = dem();
  inverse_ = d.inverseGeotransform();
  const int sizes[2] = {options_.tileSize, std::min(options_.tileSize, kSmallTile)};
  for (int l = 0; l < 2; ++l) {
    const std::int64_t s = sizes[l];
    levels_[l] = {static_cast<int>(s), d.width > 1 ? (d.width - 1 + s - 1) / s : 0,
                  d.height > 1 ? (d.height - 1 + s - 1) / s : 0};
  }
}

std::uint64_t RasterSampler::tileKey(double x, double y, int level) const {
  const DemTerrain& d = dem();
  const Level& L = levels_[level];
  if (L.tilesX == 0 || L.tilesY == 0) return kOff;  // one row or column of pixels: no cells
  const auto [col, row] = d.pixelOf(x, y, inverse_);
  if (!(col >= 0 && col <= d.width && row >= 0 && row <= d.height)) return kOff;  // NaN too
  // The cell (square of four centres) below the point, clamped onto the cells: a point on the
  // outermost centres' lines (the outer half-pixel rule put it there) belongs to the cells
  // beside them, and the tile's apron holds the neighbours of any cell.
  const auto cell = [](double p, int size) {
    return std::clamp<std::int64_t>(static_cast<std::int64_t>(std::floor(p - 0.5)), 0, size - 2);
  };
  const std::int64_t tx = cell(col, d.width) / L.size, ty = cell(row, d.height) / L.size;
  return static_cast<std::uint64_t>(ty * L.tilesX + tx) << 1 | static_cast<std::uint64_t>(level);
}

RasterSampler::Tile RasterSampler::build(std::uint64_t key, std::vector<double>& window) const {
  const DemTerrain& d = dem();
  const Level& L = levels_[key & 1];
  const std::int64_t s = L.size, index = static_cast<std::int64_t>(key >> 1);
  const std::int64_t tx = index % L.tilesX, ty = index / L.tilesX;
  // The tile's cells are [tx s, (tx + 1) s) x [ty s, (ty + 1) s); its pixels one more on each
  // side (the far corners of the last cells, and the apron).
  const auto span = [s](std::int64_t t, int size) {
    const std::int64_t lo = std::max<std::int64_t>(0, t * s - 1);
    const std::int64_t hi = std::min<std::int64_t>(size - 1, (t + 1) * s + 1);
    return std::pair<int, int>{static_cast<int>(lo), static_cast<int>(hi - lo + 1)};
  };
  const auto [c0, w] = span(tx, d.width);
  const auto [r0, h] = span(ty, d.height);
  {
    const std::lock_guard<std::mutex> hold(readLock_);  // one GDAL dataset: one read at a time
    windows_.read(c0, r0, w, h, window);
  }

  // loadDem's vertices for these pixels (the same arithmetic, so the same bits) and the raster
  // rule's triangles, in the whole terrain's order.
  Mesh mesh;
  mesh.vertices.resize(window.size());
  for (int j = 0; j < h; ++j) {
    for (int i = 0; i < w; ++i) {
      const std::size_t k = static_cast<std::size_t>(j) * w + i;
      const auto xy = d.pixelCentre(static_cast<double>(c0 + i), static_cast<double>(r0 + j));
      mesh.vertices[k] = Eigen::Vector3d(xy[0], xy[1], window[k]);
    }
  }
  RasterGrid(w, h, {}).appendTriangles(mesh, [&](std::uint32_t v) { return !std::isnan(window[v]); });
  Tile tile;
  tile.key = key;
  if (!mesh.indices.empty()) {
    tile.index.emplace(mesh, dem().mapping);
    tile.bytes = tile.index->memoryBytesNow();
  }
  tile.bytes += sizeof(Tile) + 64;
  return tile;
}

const RasterSampler::Tile* RasterSampler::cached(std::uint64_t key) {
  const auto it = byKey_.find(key);
  if (it == byKey_.end()) return nullptr;
  tiles_.splice(tiles_.begin(), tiles_, it->second);  // most recently used
  return &tiles_.front();
}

void RasterSampler::keep(Tile tile) {
  ++tilesBuilt_;
  cachedBytes_ += tile.bytes;
  tiles_.push_front(std::move(tile));
  byKey_[tiles_.front().key] = tiles_.begin();
  while (cachedBytes_ > options_.cacheBytes && tiles_.size() > 1) {
    cachedBytes_ -= tiles_.back().bytes;
    byKey_.erase(tiles_.back().key);
    tiles_.pop_back();
  }
}

void RasterSampler::answer(const Tile& tile, std::span<const std::uint32_t> which, std::span<const double> xs,
                           std::span<const double> ys, std::span<const double> zs,
                           std::span<std::optional<double>> out) const {
  if (!tile.index) {
    for (const std::uint32_t i : which) out[i] = std::nullopt;
    return;
  }
  constexpr double kTop = std::numeric_limits<double>::infinity();
  std::vector<Point2> points(which.size());
  std::vector<double> below(which.size());
  std::vector<std::optional<double>> answers(which.size());
  for (std::size_t k = 0; k < which.size(); ++k) {
    const std::uint32_t i = which[k];
    const Eigen::Vector3d m = dem().mapping.toMapped(Eigen::Vector3d(xs[i], ys[i], zs.empty() ? 0.0 : zs[i]));
    points[k] = {m.x(), m.y()};
    below[k] = zs.empty() ? kTop : m.z();
  }
  tile.index->heightsBelow(points, below, answers);
  for (std::size_t k = 0; k < which.size(); ++k) out[which[k]] = answers[k];
}

void RasterSampler::heights(std::span<const double> xs, std::span<const double> ys, std::span<const double> zs,
                            std::span<std::optional<double>> out) {
  const std::size_t n = xs.size();
  if (ys.size() != n || (!zs.empty() && zs.size() != n) || out.size() < n) {
    throw Error("RasterSampler::heights: " + std::to_string(n) + " x, " + std::to_string(ys.size()) + " y, " +
                std::to_string(zs.size()) + " z and room for " + std::to_string(out.size()) + " answers");
  }
  // Each point's large tile, and how many points each has: a large tile pays for its build
  // (about 60 ns a triangle) when many points share it, or when it is cached already; the other
  // points take small tiles (4 cells a side: windows of 7 x 7 pixels), so a few points spread
  // over a huge raster build little more than their own cells.
  std::vector<std::uint64_t> keys(n);
  batch::inSlices(n, 0, 4096, [&](std::size_t lo, std::size_t hi) {
    for (std::size_t i = lo; i < hi; ++i) keys[i] = tileKey(xs[i], ys[i], 0);
  });
  std::unordered_map<std::uint64_t, std::uint32_t> perLarge;
  for (std::size_t i = 0; i < n; ++i) {
    if (keys[i] != kOff) ++perLarge[keys[i]];
  }
  std::unordered_map<std::uint64_t, std::vector<std::uint32_t>> byTile;
  for (std::size_t i = 0; i < n; ++i) {
    std::uint64_t key = keys[i];
    if (key == kOff) {
      out[i] = std::nullopt;
      continue;
    }
    if (perLarge[key] < kLargeTilePoints && !byKey_.count(key)) key = tileKey(xs[i], ys[i], 1);
    byTile[key].push_back(static_cast<std::uint32_t>(i));
  }
  // Cached tiles answer at once; the others are built a few at a time on every core (each
  // thread reads its window in turn, then builds its index), answer, and join the cache.
  std::vector<std::uint64_t> missing;
  std::vector<std::pair<const Tile*, const std::vector<std::uint32_t>*>> ready;
  for (const auto& [key, which] : byTile) {
    if (const Tile* t = cached(key)) {
      ready.push_back({t, &which});
    } else {
      missing.push_back(key);
    }
  }
  batch::inSlices(ready.size(), 0, 1, [&](std::size_t lo, std::size_t hi) {
    for (std::size_t k = lo; k < hi; ++k) answer(*ready[k].first, *ready[k].second, xs, ys, zs, out);
  });
  std::sort(missing.begin(), missing.end());  // neighbouring windows, read in order
  const std::size_t threads = std::max(1u, std::min(4u, std::thread::hardware_concurrency()));
  for (std::size_t first = 0; first < missing.size(); first += threads) {
    const std::size_t count = std::min(threads, missing.size() - first);
    std::vector<Tile> built(count);
    std::exception_ptr failure;
    std::mutex failureLock;
    batch::inSlices(count, static_cast<unsigned>(count), 1, [&](std::size_t lo, std::size_t hi) {
      std::vector<double> window;
      for (std::size_t k = lo; k < hi; ++k) {
        try {
          built[k] = build(missing[first + k], window);
          answer(built[k], std::as_const(byTile).at(missing[first + k]), xs, ys, zs, out);
        } catch (...) {
          const std::lock_guard<std::mutex> hold(failureLock);
          if (!failure) failure = std::current_exception();
        }
      }
    });
    if (failure) std::rethrow_exception(failure);
    for (Tile& t : built) keep(std::move(t));
  }
}

}  // namespace qota
