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
  // rule's triangles, in the whole terrain's order: the grid mesh's index is that mesh's.
  Tile tile;
  tile.key = key;
  const std::size_t n = window.size();
  if ((key & 1) == 0) {
    // A large tile (level 0): the lean grid of the same mapped vertices, when they make one.
    std::vector<Point2> corners(n);
    std::vector<double> heights(n);
    bool any = false;
    for (int j = 0; j < h; ++j) {
      for (int i = 0; i < w; ++i) {
        const std::size_t k = static_cast<std::size_t>(j) * w + i;
        const auto xy = d.pixelCentre(static_cast<double>(c0 + i), static_cast<double>(r0 + j));
        const Eigen::Vector3d m = d.mapping.toMapped(Eigen::Vector3d(xy[0], xy[1], window[k]));
        corners[k] = {m.x(), m.y()}, heights[k] = m.z();
        any = any || !std::isnan(window[k]);
      }
    }
    if (!any) {
      tile.bytes = sizeof(Tile) + 64;
      return tile;
    }
    if (tile.lean.setUpLattice(static_cast<std::uint64_t>(w), static_cast<std::uint64_t>(h), corners, heights)) {
      if (tile.lean.readsVertexCoordinates()) tile.corners = std::move(corners);
      if (tile.lean.readsVertexHeights()) tile.heights = std::move(heights);
      tile.bytes = sizeof(Tile) + 64 + tile.lean.memoryBytes() + tile.corners.size() * sizeof(Point2) +
                   tile.heights.size() * sizeof(double);
      return tile;
    }
  }
  std::vector<Eigen::Vector3d> vertices(n);
  for (int j = 0; j < h; ++j) {
    for (int i = 0; i < w; ++i) {
      const std::size_t k = static_cast<std::size_t>(j) * w + i;
      const auto xy = d.pixelCentre(static_cast<double>(c0 + i), static_cast<double>(r0 + j));
      vertices[k] = Eigen::Vector3d(xy[0], xy[1], window[k]);
    }
  }
  const GridMesh grid{.width = w, .height = h, .vertices = vertices};
  if (grid.polygonCount() > 0) {
    tile.index.emplace(grid, dem().mapping);
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
  leanTilesBuilt_ += tile.lean.isLean();
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
                           std::span<std::optional<double>> results, std::vector<std::uint32_t>& left) const {
  if (tile.empty()) {
    std::fill(results.begin(), results.end(), std::nullopt);
    return;
  }
  constexpr double kTop = std::numeric_limits<double>::infinity();
  std::vector<Point2> points(which.size());
  std::vector<double> below(which.size());
  for (std::size_t k = 0; k < which.size(); ++k) {
    const std::uint32_t i = which[k];
    const Eigen::Vector3d m = dem().mapping.toMapped(Eigen::Vector3d(xs[i], ys[i], zs.empty() ? 0.0 : zs[i]));
    points[k] = {m.x(), m.y()};
    below[k] = zs.empty() ? kTop : m.z();
  }
  if (tile.index) {
    tile.index->heightsBelow(points, below, results);
    return;
  }
  // The index's answer where the lean grid decides it (its `h <= z` as heightsBelow has it).
  std::vector<double> heights(which.size());
  std::vector<std::uint8_t> decided(which.size());
  tile.lean.leanHeights(tile.corners, tile.heights, points, heights.data(), decided.data());
  for (std::size_t k = 0; k < which.size(); ++k) {
    const bool hit = decided[k] == detail::GridPath::kHeight && heights[k] <= below[k];
    results[k] = hit ? std::optional<double>(heights[k]) : std::nullopt;
    if (decided[k] == detail::GridPath::kUndecided) left.push_back(which[k]);
  }
}

namespace {

// Dense ids for tile keys, in the order they first come: open addressing, a few nanoseconds a
// key (a node-based map takes several times that, and grouping a batch is serial).
class KeyIds {
 public:
  std::uint32_t idOf(std::uint64_t key) {
    if (2 * (keys_.size() + 1) > slots_.size()) grow();
    for (std::size_t s = slotOf(key);; s = (s + 1) & (slots_.size() - 1)) {
      if (slots_[s] == kEmpty) {
        slots_[s] = static_cast<std::uint32_t>(keys_.size());
        keys_.push_back(key);
        return slots_[s];
      }
      if (keys_[slots_[s]] == key) return slots_[s];
    }
  }
  const std::vector<std::uint64_t>& keys() const { return keys_; }

 private:
  static constexpr std::uint32_t kEmpty = ~std::uint32_t{0};
  std::size_t slotOf(std::uint64_t key) const {
    return static_cast<std::size_t>((key * 0x9e3779b97f4a7c15ull) >> 32) & (slots_.size() - 1);
  }
  void grow() {
    slots_.assign(std::max<std::size_t>(64, 2 * slots_.size()), kEmpty);
    for (std::uint32_t id = 0; id < keys_.size(); ++id) {
      std::size_t s = slotOf(keys_[id]);
      while (slots_[s] != kEmpty) s = (s + 1) & (slots_.size() - 1);
      slots_[s] = id;
    }
  }
  std::vector<std::uint32_t> slots_;
  std::vector<std::uint64_t> keys_;
};

}  // namespace

RasterSampler::Groups RasterSampler::group(std::span<const std::uint32_t> points, std::span<const std::uint64_t> keys) {
  // The points in order of their group (a counting sort by id): each group's points stay in
  // increasing order.
  KeyIds ids;
  std::vector<std::uint32_t> id(points.size());
  for (std::size_t k = 0; k < points.size(); ++k) id[k] = ids.idOf(keys[k]);
  Groups g;
  g.keys = ids.keys();
  g.offsets.assign(g.keys.size() + 1, 0);
  for (const std::uint32_t i : id) ++g.offsets[i + 1];
  for (std::size_t i = 0; i < g.keys.size(); ++i) g.offsets[i + 1] += g.offsets[i];
  g.points.resize(points.size());
  std::vector<std::uint32_t> at(g.offsets.begin(), g.offsets.end() - 1);
  for (std::size_t k = 0; k < points.size(); ++k) g.points[at[id[k]]++] = points[k];
  return g;
}

std::vector<std::uint32_t> RasterSampler::answerByTile(const Groups& groups, std::span<const double> xs,
                                                       std::span<const double> ys, std::span<const double> zs,
                                                       std::span<std::optional<double>> out) {
  // Cached tiles answer at once; the others are built a few at a time on every core (each
  // thread reads its window in turn, then builds its tile), answer, and join the cache.
  std::vector<std::uint32_t> missing;  // groups
  std::vector<std::pair<const Tile*, std::uint32_t>> ready;
  for (std::uint32_t k = 0; k < groups.keys.size(); ++k) {
    if (const Tile* t = cached(groups.keys[k])) {
      ready.push_back({t, k});
    } else {
      missing.push_back(k);
    }
  }
  // Answers in the groups' order (each tile writes its own run; writing into `out` by point
  // would have the threads share cache lines), then put in place.
  std::vector<std::optional<double>> results(groups.points.size());
  const auto resultsOf = [&](std::uint32_t k) {
    return std::span<std::optional<double>>(results).subspan(groups.offsets[k],
                                                             groups.offsets[k + 1] - groups.offsets[k]);
  };
  std::vector<std::vector<std::uint32_t>> left(ready.size());
  batch::inSlices(ready.size(), 0, 1, [&](std::size_t lo, std::size_t hi) {
    for (std::size_t k = lo; k < hi; ++k) {
      answer(*ready[k].first, groups.of(ready[k].second), xs, ys, zs, resultsOf(ready[k].second), left[k]);
    }
  });
  // Neighbouring windows, read in order.
  std::sort(missing.begin(), missing.end(),
            [&](std::uint32_t a, std::uint32_t b) { return groups.keys[a] < groups.keys[b]; });
  // Built a chunk at a time on every core, a chunk holding a large tile per thread or as many
  // small ones in the same pixels (starting threads for every two small tiles would cost more
  // than the tiles).
  const std::size_t threads = std::max(1u, std::min(4u, std::thread::hardware_concurrency()));
  const auto pixels = [&](std::uint64_t key) {
    const std::uint64_t side = static_cast<std::uint64_t>(levels_[key & 1].size) + 3;
    return side * side;
  };
  const std::uint64_t chunkPixels = threads * pixels(0);
  for (std::size_t first = 0, count = 0; first < missing.size(); first += count) {
    std::uint64_t sum = pixels(groups.keys[missing[first]]);
    count = 1;
    while (first + count < missing.size() && sum + pixels(groups.keys[missing[first + count]]) <= chunkPixels) {
      sum += pixels(groups.keys[missing[first + count++]]);
    }
    std::vector<Tile> built(count);
    std::vector<std::vector<std::uint32_t>> leftHere(count);
    std::exception_ptr failure;
    std::mutex failureLock;
    batch::inSlices(count, static_cast<unsigned>(std::min(threads, count)), 1, [&](std::size_t lo, std::size_t hi) {
      std::vector<double> window;
      for (std::size_t k = lo; k < hi; ++k) {
        try {
          const std::uint32_t gk = missing[first + k];
          built[k] = build(groups.keys[gk], window);
          answer(built[k], groups.of(gk), xs, ys, zs, resultsOf(gk), leftHere[k]);
        } catch (...) {
          const std::lock_guard<std::mutex> hold(failureLock);
          if (!failure) failure = std::current_exception();
        }
      }
    });
    if (failure) std::rethrow_exception(failure);
    for (Tile& t : built) keep(std::move(t));
    for (auto& l : leftHere) left.push_back(std::move(l));
  }
  for (std::size_t j = 0; j < results.size(); ++j) out[groups.points[j]] = results[j];
  std::vector<std::uint32_t> all;
  for (const auto& l : left) all.insert(all.end(), l.begin(), l.end());
  std::sort(all.begin(), all.end());
  return all;
}

void RasterSampler::heights(std::span<const double> xs, std::span<const double> ys, std::span<const double> zs,
                            std::span<std::optional<double>> out) {
  const std::size_t n = xs.size();
  if (ys.size() != n || (!zs.empty() && zs.size() != n) || out.size() < n || n >= 0xffffffffu) {
    throw Error("RasterSampler::heights: " + std::to_string(n) + " x, " + std::to_string(ys.size()) + " y, " +
                std::to_string(zs.size()) + " z and room for " + std::to_string(out.size()) + " answers");
  }
  // Each point's large tile, and how many points each has: a large tile pays for its build
  // (a few nanoseconds a pixel) when many points share it, or when it is cached already; the
  // other points take small tiles (4 cells a side: windows of 7 x 7 pixels), so a few points
  // spread over a huge raster build little more than their own cells.
  std::vector<std::uint64_t> keys(n);
  batch::inSlices(n, 0, 4096, [&](std::size_t lo, std::size_t hi) {
    for (std::size_t i = lo; i < hi; ++i) keys[i] = tileKey(xs[i], ys[i], 0);
  });
  std::vector<std::uint32_t> on;  // the points on the cells
  on.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    if (keys[i] == kOff) {
      out[i] = std::nullopt;
    } else {
      keys[on.size()] = keys[i];
      on.push_back(static_cast<std::uint32_t>(i));
    }
  }
  keys.resize(on.size());
  Groups groups = group(on, keys);
  // Groups too small for a large tile not in the cache go to small tiles.
  bool small = false;
  for (std::size_t k = 0; k < groups.keys.size() && !small; ++k) {
    small = groups.offsets[k + 1] - groups.offsets[k] < kLargeTilePoints && !byKey_.count(groups.keys[k]);
  }
  if (small) {
    for (std::size_t k = 0; k < groups.keys.size(); ++k) {
      if (groups.offsets[k + 1] - groups.offsets[k] >= kLargeTilePoints || byKey_.count(groups.keys[k])) continue;
      for (std::uint32_t j = groups.offsets[k]; j < groups.offsets[k + 1]; ++j) {
        const std::uint32_t i = groups.points[j];
        keys[j] = tileKey(xs[i], ys[i], 1);
      }
    }
    for (std::size_t k = 0; k < groups.keys.size(); ++k) {
      if (groups.offsets[k + 1] - groups.offsets[k] < kLargeTilePoints && !byKey_.count(groups.keys[k])) continue;
      std::fill(keys.begin() + groups.offsets[k], keys.begin() + groups.offsets[k + 1], groups.keys[k]);
    }
    const std::vector<std::uint32_t> points = std::move(groups.points);
    groups = group(points, keys);
  }
  const std::vector<std::uint32_t> left = answerByTile(groups, xs, ys, zs, out);
  // The points the large tiles' lean grids left (near a side, beside a hole): small tiles,
  // whose indexes answer every point.
  if (left.empty()) return;
  std::vector<std::uint64_t> smallKeys(left.size());
  for (std::size_t k = 0; k < left.size(); ++k) smallKeys[k] = tileKey(xs[left[k]], ys[left[k]], 1);
  if (!answerByTile(group(left, smallKeys), xs, ys, zs, out).empty()) {
    throw Error("RasterSampler: a small tile left points unanswered");
  }
}

}  // namespace qota
