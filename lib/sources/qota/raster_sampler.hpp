// Heights under points of a raster of any size, read tile by tile: the answers of loadDem's
// whole terrain under its CartesianIndex (dem.hpp: pixel centres, the raster rule's triangles,
// nodata holes), bit for bit, in memory bounded by a tile cache instead of by the raster.
//
// A tile is a square of tileSize x tileSize cells (the squares between four pixel centres),
// made from a window of pixels one cell wider on every side: every triangle that can hold a point
// of the tile's cells, neighbours across its sides included, is in it, with the vertices, mapping
// (origin at the raster's centre) and triangle order of the whole terrain. A small tile is that
// window's index (built from a GridMesh), so a point on a tile's side, a pixel centre or beside a
// hole gets the same triangle, plane and bits as from the whole raster. A large tile is the
// index's lean grid alone (GridPath::setUpLattice), which answers the points clearly inside a
// triangle or a hole with the index's own arithmetic and leaves the rest to small tiles; tests
// hold both to the whole terrain on real and synthetic rasters.
//
// Points are world (x, y) on the raster's footprint: callers apply the outer half-pixel rule
// (DemTerrain::surfacePoint) first, as for the whole terrain; a point off the cells has no
// terrain. Batches are grouped by tile, so random points over a raster far larger than the cache
// read each tile once per batch; a large tile is built only where a batch has many points (or it
// is cached), else small tiles of 16 cells, so sparse points cost a small window each.
#pragma once

#include <array>
#include <cstdint>
#include <list>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <unordered_map>
#include <vector>

#include "qota/dem.hpp"
#include "qota/grid_path.hpp"
#include "qota/terrain.hpp"

namespace qota {

class RasterSampler {
 public:
  struct Options {
    int band = 0;                           // as DemOptions::band
    bool lonLatAsCartesian = true;          // heights at points only (see DemOptions)
    std::uint64_t cacheBytes = 128u << 20;  // the tiles' indexes kept between batches
    int tileSize = 256;                     // cells per tile side
  };

  // Opens the raster (describeDem's checks); reads nothing else yet. Throws qota::Error.
  RasterSampler(const std::string& path, const Options& options);

  const DemTerrain& dem() const { return windows_.dem(); }

  // out[i]: the highest terrain height at or below zs[i] (the top when zs is empty) at world
  // (xs[i], ys[i]), in the raster's own unit; std::nullopt for none. Tiles missing from the
  // cache are built on every core. Not to be called from two threads at once (it keeps the cache).
  // Throws qota::Error for spans of different sizes, or 2^32 - 1 points or more in one call.
  void heights(std::span<const double> xs, std::span<const double> ys, std::span<const double> zs,
               std::span<std::optional<double>> out);

  // What it has done: tiles built (large tiles made as lean grids among them), and the bytes of
  // the tiles cached now.
  std::uint64_t tilesBuilt() const { return tilesBuilt_; }
  std::uint64_t leanTilesBuilt() const { return leanTilesBuilt_; }
  std::uint64_t cachedBytes() const { return cachedBytes_; }

 private:
  // A small tile is an index (exact everywhere). A large tile is a lean grid alone, about 4 bytes
  // a pixel where the index would take 70: it answers the points clearly inside a triangle with
  // the index's own arithmetic (GridPath::leanHeights), and hands the others (near a triangle's
  // side, beside a hole: about 1 in 10,000 random points) to small tiles.
  struct Tile {
    std::optional<CartesianIndex> index;
    detail::GridPath lean;
    std::vector<Point2> corners;  // the vertices' mapped (u, v), where the lean tables lack them
    std::vector<double> heights;  // and their mapped h
    std::uint64_t bytes = 0;
    std::uint64_t key = 0;
    bool empty() const { return !index && !lean.isLean(); }  // no terrain in the tile
  };
  // A tile's key: its index at `level` (0: tileSize cells a side, 1: small tiles) and the level;
  // kOff for a point off the cells.
  std::uint64_t tileKey(double x, double y, int level) const;
  const Tile* cached(std::uint64_t key);  // null: not in the cache
  void keep(Tile tile);                   // into the cache, evicting the oldest
  // A tile from its window (window: a reusable buffer); thread-safe.
  Tile build(std::uint64_t key, std::vector<double>& window) const;
  // results[k] for point which[k], every point in the tile; the points a lean tile leaves to
  // small tiles are appended to `left` (their results are placeholders).
  void answer(const Tile& tile, std::span<const std::uint32_t> which, std::span<const double> xs,
              std::span<const double> ys, std::span<const double> zs, std::span<std::optional<double>> results,
              std::vector<std::uint32_t>& left) const;
  // Points grouped by tile key: group k's points are points[offsets[k] .. offsets[k + 1]), in
  // increasing order.
  struct Groups {
    std::vector<std::uint64_t> keys;
    std::vector<std::uint32_t> offsets, points;
    std::span<const std::uint32_t> of(std::size_t k) const {
      return std::span<const std::uint32_t>(points).subspan(offsets[k], offsets[k + 1] - offsets[k]);
    }
  };
  static Groups group(std::span<const std::uint32_t> points, std::span<const std::uint64_t> keys);
  // Answers the groups' points, from the cache or building the missing tiles on every core;
  // returns the points left to small tiles.
  std::vector<std::uint32_t> answerByTile(const Groups& groups, std::span<const double> xs, std::span<const double> ys,
                                          std::span<const double> zs, std::span<std::optional<double>> out);

  static constexpr std::uint64_t kOff = ~std::uint64_t{0};
  Options options_;
  DemWindows windows_;
  struct Level {
    int size = 0;                         // cells a side
    std::int64_t tilesX = 0, tilesY = 0;  // tiles across and down
  };
  static constexpr int kSmallTile = 4;
  static constexpr std::uint32_t kLargeTilePoints = 256;  // points a batch needs in a large tile to build it
  Level levels_[2];
  std::array<double, 6> inverse_{};  // the raster's inverse geotransform
  // Least recently used at the back.
  std::list<Tile> tiles_;
  std::unordered_map<std::uint64_t, std::list<Tile>::iterator> byKey_;
  std::uint64_t cachedBytes_ = 0, tilesBuilt_ = 0, leanTilesBuilt_ = 0;
  mutable std::mutex readLock_;  // the dataset reads one window at a time
};

}  // namespace qota
