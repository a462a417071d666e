// Shadows and sunlight hours of a raster of any size, one tile at a time, in memory bounded by
// the tile instead of by the raster, equal pixel for pixel to the whole raster's (shadowMask and
// sunlightHours over localFrame).
//
// A tile is computed in a window of the raster: the tile and a halo around it, holding every
// triangle that can shade one of its pixels. Every window's frame is the whole raster's
// (windowFrame: the same origin, body, height range, vertex bits, triangles and corner order),
// and a pixel's shadow is decided by exact tests against the triangles its ray may meet, so what
// the window holds decides nothing but which triangles are there to test.
//
// The halo. A ray from a pixel toward the light rises light.z per unit of its length and moves
// |light.xy| across; an occluder lies no higher than the frame's top zTop (the raster's highest
// pixel, or 0 on an ellipsoid when that is higher: the ellipsoid falls away below the tangent plane
// at the centre, so no point at height h stands above max(h, 0) in the frame), so a ray meets
// terrain only within D = (zTop - the tile's lowest pixel) |light.xy| / light.z of its pixel, seen
// from above, and only toward the light. In pixels, that displacement is turned by the grid's
// Jacobian (exact for flat frames, whose grid is affine; on an ellipsoid, the larger of its
// values at the tile and at the far end of the reach, with a quarter more for its change in
// between), plus 3 pixels: the triangle that holds the meeting point, the ring of triangles round
// every tile pixel (attached shadow), and the outer half pixel the window's frame adds on its sides
// inside the raster (terrain the raster does not have, kept beyond any ray's reach by this).
// Sides away from the light get the 3 pixels only.
//
// On an ellipsoid a low light reaches farther than that plane allows (at or below the tile's
// horizon, without bound), but not past the body's curve. Every normal curvature of the
// ellipsoid is at least b / a^2, so it lies inside the ball of radius rM = a^2 / b touching it
// at any of its points (Blaschke's rolling theorem), and all terrain (at most zTop above it)
// inside that ball grown by zTop, centred rM below the tile's centre. A ray leaves a ball once,
// so a pixel's ray meets terrain only before it leaves this one: a distance bounded from the
// pixel's height, its offset from the centre and the light's rise (reach in shadow_tiles.cpp).
// The reach is the smaller of the two bounds. A light more than the dip of the horizon (and the
// tilt across the tile) below a tile's horizon needs none: every pixel's ray enters the body,
// which shades it whatever the terrain, in the tile's window as over the whole raster.
//
// Voids are filled for occlusion (fillVoids) by onion peeling, whose value at a void pixel depends
// on the pixels within twice its fill level: each window's heights are filled over a larger
// window, grown until every void pixel of the window passes that test, so its fill is the whole
// raster's. A void too wide for the memory allowed is refused, with its size.
//
// Not tiled: a raster closed round the globe (its frame has a seam and poles); it is shadowed
// whole when it fits, else refused. A window over the memory allowed is refused with its size
// (a low sun's reaches far: smaller tiles take narrower windows).
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "qota/dem.hpp"
#include "qota/height_blocks.hpp"
#include "qota/shadow.hpp"
#include "qota/shadow_frame.hpp"
#include "qota/sunlight.hpp"

namespace qota {

class ShadowTiles {
 public:
  // Opens the raster and reads it once, by rows, for what every window shares: the height range
  // and the frame's centre (frameBasis, completeBasis). progress: that pass's fraction. bytes:
  // the most the pass holds at once (rows of kPassBytesPerPixel a pixel; 0: kPassBytes).
  ShadowTiles(const std::string& path, const DemOptions& dem, const FrameOptions& frame, const Progress& progress = {},
              std::uint64_t bytes = 0);
  static constexpr std::uint64_t kPassBytes = 24ull << 20;
  static constexpr std::uint64_t kPassBytesPerPixel = 16;
  // Heights of a window of the raster, as DemWindows reads them: row-major, in the raster's unit
  // (scale and offset applied), NaN where there is no data.
  using HeightReader = std::function<void(const PixelWindow& window, std::vector<double>& heights)>;
  // The same from any source of heights (a Dask array, ...); description: the raster's size,
  // geotransform, CRS, vertical unit and path (for messages), as describeDem gives them. `read`
  // may be called from one thread at a time only.
  ShadowTiles(const DemTerrain& description, HeightReader read, const FrameOptions& frame,
              const Progress& progress = {}, std::uint64_t bytes = 0);
  // Text that makes the same tiles in another process (restore), without reading the raster
  // again: the description (band and nodata value included), the frame's options, what the pass
  // over the heights found (the numbers bit for bit) and the heights' block hashes
  // (heightBlocks), the qota version, and a checksum of all of it.
  std::string state() const;
  // Tiles from a state. Throws qota::Error, naming what is wrong, for a state that is damaged or
  // edited (its checksum), of another qota version, or holding values no raster gives. Tiles
  // restored have no source: only the ...FromHeights calls, whose heights are checked against
  // the state's block hashes.
  static ShadowTiles restore(const std::string& state);
  // The same, reading the raster at `path` again (a batch job's tile, without the pass over the
  // heights another job made). Throws qota::Error naming the field when the raster or the frame's
  // options are not the state's (its size, geotransform, CRS, band, nodata value, vertical unit;
  // --flat, --pixel-size, -z, -s). Every window read later is checked against the state's block
  // hashes, so another raster's heights under the same name are refused when read.
  static ShadowTiles restore(const std::string& state, const std::string& path, const DemOptions& dem,
                             const FrameOptions& frame);
  // The most bytes a state may take (a state file larger is refused unread).
  static constexpr std::uint64_t kMostStateBytes = 32ull << 20;
  ~ShadowTiles();
  ShadowTiles(ShadowTiles&&) noexcept;
  ShadowTiles& operator=(ShadowTiles&&) noexcept;

  const DemTerrain& dem() const { return basis_.raster; }
  const FrameBasis& basis() const { return basis_; }
  // The whole raster's frame without its pixels: description, centre, body, heights, pixel size,
  // towardSun and horizonSlack's inputs.
  const LocalFrame& frame() const { return basis_.shared; }
  // Pixels with data in the raster.
  std::uint64_t validPixels() const { return validPixels_; }
  // The raster's heights hashed by blocks in the pass over them: what every read is checked
  // against, and (whole()) the identity of the heights in a tile's metadata.
  const HeightBlocks& heightBlocks() const { return blocks_; }
  // The smallest window of whole hash blocks that holds `window`: the heights ...FromHeights
  // takes are those of such a window (they are checked block by block).
  PixelWindow checkableWindow(const PixelWindow& window) const { return blocks_.alignedOut(window); }

  // Pixels of halo beyond each side of `tile` (west, east, north, south: columns before and after,
  // rows above and below) for these lights, clipped to the raster. tileLowest: the tile's lowest
  // valid height in metres, or the raster's (frame().minHeight) for the worst case.
  std::array<int, 4> halo(const PixelWindow& tile, const std::vector<Eigen::Vector3d>& lights, double tileLowest) const;
  // The window a tile is computed in: the tile and its halo.
  PixelWindow windowOf(const PixelWindow& tile, const std::array<int, 4>& halo) const;

  // The most bytes a window takes at its peak, per pixel (measured; see the .cpp): more at a low
  // light, whose rays cross more triangles. lights: the run's (their lowest decides).
  static std::uint64_t bytesPerWindowPixel();  // (the lowest lights')
  static std::uint64_t bytesPerWindowPixel(const std::vector<Eigen::Vector3d>& lights);
  // The same for a whole raster's shadows in memory (loadDem, localFrame, shadowMask), per pixel.
  static std::uint64_t bytesPerWholePixel(const std::vector<Eigen::Vector3d>& lights);
  // The most pixels any of `tiles`' windows takes under these lights: at least what mask and hours
  // read for each, planned from the blocks' height ranges (HeightBlocks::rangeOver) without
  // reading any heights. For estimates and for choosing a tile size.
  std::uint64_t largestWindowPixels(const std::vector<PixelWindow>& tiles,
                                    const std::vector<Eigen::Vector3d>& lights) const;
  // The largest square tile side (a multiple of `multiple`, at least `multiple`) whose worst-case
  // window under these lights fits in `bytes`; 0 when none does.
  int tileSideFor(std::uint64_t bytes, const std::vector<Eigen::Vector3d>& lights, int multiple) const;

  // The light at every pixel of `tile` (row-major), as shadowMask gives it over the whole raster.
  // bytes: the most the window may take (bytesPerWindowPixel each); 0: no limit. Throws qota::Error
  // when it would take more, naming what it needs.
  std::vector<Light> mask(const PixelWindow& tile, const Eigen::Vector3d& light, const IndexOptions& options = {},
                          unsigned threads = 0, ShadowSearch search = ShadowSearch::Strips,
                          std::uint64_t bytes = 0) const;
  // Hours of direct sunlight at every pixel of `tile`, as sunlightHours gives them over the whole
  // raster (the same steps and rule). The steps whose own window is at most twice the smallest
  // share one window, the low suns' another (a day's sunrise need not lengthen its noon's): each
  // step's light is found here (sunlightSteps's lights serve tileSideFor and hoursFromHeights).
  SunlightHours hours(const PixelWindow& tile, double startJulianDay, double endJulianDay, double stepHours,
                      const IndexOptions& options = {}, ShadowSearch search = ShadowSearch::Strips,
                      std::uint64_t bytes = 0, unsigned threads = 0) const;
  // The lights of the steps of a span (qota::sunlightSteps, sunlightHours's) with the Sun above
  // the horizon at the centre less the frame's slack bound (sunCanLight): the lights a tile's halo
  // must serve. slack: how far below the centre's horizon the Sun may be while some pixel sees it
  // (degrees; the whole raster's, or larger). Throws qota::Error for a step sunlightHours refuses.
  std::vector<Eigen::Vector3d> sunlightSteps(double startJulianDay, double endJulianDay, double stepHours,
                                             double slack) const;
  // mask and hours from heights given instead of read: `window` (and its heights, as HeightReader
  // gives them) must hold the tile and its halo, and enough around its voids to fill them as over
  // the whole raster (see above); else qota::Error says what it lacks. `window` is made of whole
  // hash blocks (checkableWindow), and its heights are checked against the raster's block hashes:
  // another raster's are refused. For Dask: `window` is a block with its overlap (at least
  // haloFor's) made checkable, `tile` the block.
  std::vector<Light> maskFromHeights(const PixelWindow& window, std::vector<double> heights, const PixelWindow& tile,
                                     const Eigen::Vector3d& light, const IndexOptions& options = {},
                                     unsigned threads = 0, ShadowSearch search = ShadowSearch::Strips) const;
  SunlightHours hoursFromHeights(const PixelWindow& window, std::vector<double> heights, const PixelWindow& tile,
                                 double startJulianDay, double endJulianDay, double stepHours,
                                 const std::vector<Eigen::Vector3d>& lights, const IndexOptions& options = {},
                                 ShadowSearch search = ShadowSearch::Strips, unsigned threads = 0) const;
  // The most halo any tile of this size (at most; tiles at the raster's edges are smaller) needs
  // under these lights, per side (west, east, north, south): an overlap for blocks of that size.
  std::array<int, 4> haloFor(int tileWidth, int tileHeight, const std::vector<Eigen::Vector3d>& lights) const;
  // The same for tiles whose lowest valid pixel is at least `lowest` metres (haloFor: the raster's
  // lowest).
  std::array<int, 4> haloAtMost(int tileWidth, int tileHeight, const std::vector<Eigen::Vector3d>& lights,
                                double lowest) const;

  // A bound on the whole raster's LocalFrame::horizonSlack, from its outermost pixels (the tilt
  // between the centre's up and a pixel's is largest on the raster's rim), without reading it all.
  double horizonSlack() const { return slack_; }

 private:
  struct Source;
  ShadowTiles() = default;
  void passOverHeights(const Progress& progress, std::uint64_t bytes);
  // The filled heights (metres) and validity of `window`, equal to the whole raster's fill there.
  void readFilled(const PixelWindow& window, std::vector<double>& heights, std::vector<std::uint8_t>& valid,
                  std::uint64_t bytes) const;
  // The tile's lowest valid pixel above its centre's tangent plane (+inf for none); heights in
  // metres, valid per pixel.
  double lowestOf(const PixelWindow& tile, std::vector<double> heights, const std::vector<std::uint8_t>& valid) const;
  LocalFrame windowOfTile(const PixelWindow& tile, const std::vector<Eigen::Vector3d>& lights, std::uint64_t bytes,
                          PixelWindow& window) const;
  // windowOfTile's steps: the tile's lowest (read from the source), and the frame over a window
  // (refused over `bytes`).
  double lowestIn(const PixelWindow& tile) const;
  LocalFrame frameOver(const PixelWindow& tile, const PixelWindow& window, std::uint64_t bytes,
                       const std::vector<Eigen::Vector3d>& lights) const;
  // The frame of a window given whole (...FromHeights), checked to hold the tile's halo and fill;
  // an empty frame for a tile without data.
  // halo before clipping to the raster.
  std::array<int, 4> reach(const PixelWindow& tile, const std::vector<Eigen::Vector3d>& lights,
                           double tileLowest) const;
  SunlightHours tileHours(const LocalFrame& frame, const PixelWindow& tile, double startJulianDay, double endJulianDay,
                          double stepHours, const IndexOptions& options, ShadowSearch search, unsigned threads) const;
  LocalFrame givenWindow(const PixelWindow& window, std::vector<double> heights, const PixelWindow& tile,
                         const std::vector<Eigen::Vector3d>& lights) const;

  std::unique_ptr<Source> source_;
  FrameBasis basis_;
  HeightBlocks blocks_;
  std::uint64_t validPixels_ = 0;
  double slack_ = 0;
};

}  // namespace qota
