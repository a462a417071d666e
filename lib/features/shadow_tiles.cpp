// Shadows of a raster tile by tile (see qota/shadow_tiles.hpp for why each tile is exact).
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

namespace qota {
namespace {

constexpr double kDeg = M_PI / 180.0;
// Cells of halo on every side beyond the reach (see the header): the meeting point's triangle,
// the tile cells' rings, the window's own outer half pixel.
constexpr int kHaloCells = 3;

std::string cells(const CellWindow& w) {
  return "(" + std::to_string(w.col) + ", " + std::to_string(w.row) + ") + " + std::to_string(w.width) + " x " +
         std::to_string(w.height);
}

// The grid's local geometry at a cell: the frame points of the cell and its east and south
// neighbours at height 0, and the body's up there.
struct Local {
  Eigen::Vector3d origin, up, east, south;  // east, south: one column, one row on
};

}  // namespace

struct ShadowTiles::Source {
  std::unique_ptr<DemWindows> windows;  // when reading a file
  HeightReader reader;
  mutable std::mutex lock;  // one read at a time
  // The heights of w; with `blocks`, read by whole blocks and checked against their hashes (the
  // raster may not be the one the hashes were made from: a restored state's, or a file changed).
  void read(const CellWindow& w, std::vector<double>& out, const HeightBlocks* blocks, const std::string& path) const {
    const std::lock_guard<std::mutex> guard(lock);
    const CellWindow cover = blocks ? blocks->alignedOut(w) : w;
    std::vector<double> all;
    std::vector<double>& into = cover == w ? out : all;
    into.resize(cover.cellCount());
    reader(cover, into);
    if (into.size() != cover.cellCount()) {
      throw Error("a height reader gave " + std::to_string(into.size()) + " heights for " +
                  std::to_string(cover.cellCount()) + " cells");
    }
    if (blocks) blocks->check(cover, into, path);
    if (cover == w) return;
    out.resize(w.cellCount());
    for (int r = 0; r < w.height; ++r) {
      const std::size_t from = static_cast<std::size_t>(r + w.row - cover.row) * cover.width + (w.col - cover.col);
      std::copy_n(all.begin() + static_cast<std::ptrdiff_t>(from), w.width,
                  out.begin() + static_cast<std::ptrdiff_t>(r) * w.width);
    }
  }
};

namespace {

Local localAt(const FrameBasis& basis, int col, int row) {
  const int w = basis.raster.width, h = basis.raster.height;
  const int c = std::clamp(col, 0, std::max(0, w - 2)), r = std::clamp(row, 0, std::max(0, h - 2));
  const CellWindow square{c, r, std::min(2, w), std::min(2, h)};
  const LocalFrame f = windowFrame(basis, square, std::vector<double>(square.cellCount(), 0.0),
                                   std::vector<std::uint8_t>(square.cellCount(), 1));
  const auto& v = f.mesh.vertices;
  Local l;
  l.origin = v[0];
  l.up = f.upAt(v[0]);
  l.east = square.width > 1 ? Eigen::Vector3d(v[1] - v[0]) : Eigen::Vector3d::Zero();
  l.south = square.height > 1 ? Eigen::Vector3d(v[square.width] - v[0]) : Eigen::Vector3d::Zero();
  return l;
}

// The pixel displacement (columns, rows) of a frame displacement d along the surface at l: d in
// the tangent plane, in the basis of one column and one row (least squares: they are not
// orthogonal on a sheared grid). Zero for a raster one cell wide or high in that direction.
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

}  // namespace

ShadowTiles::ShadowTiles(const std::string& path, const DemOptions& demOptions, const FrameOptions& frameOptions,
                         const Progress& progress, std::uint64_t bytes)
    : source_(std::make_unique<Source>()) {
  source_->windows = std::make_unique<DemWindows>(path, demOptions);
  const DemWindows* windows = source_->windows.get();
  source_->reader = [windows](const CellWindow& w, std::vector<double>& out) {
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
  // The height range: one pass by rows, a few million cells at a time.
  double lo = INFINITY, hi = -INFINITY;
  const std::uint64_t cellsAtOnce = std::max<std::uint64_t>(1, (bytes ? bytes : kPassBytes) / kPassBytesPerCell);
  const int rowsAtOnce = static_cast<int>(std::clamp<std::uint64_t>(cellsAtOnce / std::max(1, w), 1, h));
  std::vector<double> z;
  std::vector<std::uint8_t> valid;
  blocks_ = HeightBlocks(w, h);
  for (int r = 0; r < h; r += rowsAtOnce) {
    const CellWindow rows{0, r, w, std::min(rowsAtOnce, h - r)};
    source_->read(rows, z, nullptr, path);
    blocks_.addRows(rows.row, rows.height, z);
    heightsInMetres(basis_, rows, z, valid);
    for (std::size_t i = 0; i < z.size(); ++i) {
      if (valid[i]) lo = std::min(lo, z[i]), hi = std::max(hi, z[i]), ++validCells_;
    }
    if (progress && !progress(static_cast<double>(r + rows.height) / h, "reading the height range")) {
      throw Error("shadow computation cancelled");
    }
  }
  // The centre square, for the pixel size and the triangles' turn (its fill, in a void, read
  // within a bound: a void half the raster wide is refused rather than read whole).
  const CellWindow centre{std::max(0, (w - 1) / 2), std::max(0, (h - 1) / 2), std::min(2, w), std::min(2, h)};
  readFilled(centre, z, valid, 512ull << 20);
  const LocalFrame centreFrame = windowFrame(basis_, centre, std::move(z), std::move(valid));
  completeBasis(basis_, lo, hi, centreFrame);

  // The horizon slack (LocalFrame::horizonSlack) from the rim's cells: the tilt between the
  // centre's up and a cell's grows with the angle between them, largest on the rim of a raster
  // not reaching round the globe. Up from the cells at height 0 and at the highest cell's height
  // (the up of the frame's formula moves a little with the height), and a hundredth of a degree
  // more for the in-between.
  if (basis_.shared.body.ellipsoid) {
    double cosTilt = 1;
    const LocalFrame& f = basis_.shared;
    const Eigen::RowVector3d upRow = f.body.rotation.row(2);
    for (const CellWindow& rim :
         {CellWindow{0, 0, w, 1}, CellWindow{0, h - 1, w, 1}, CellWindow{0, 0, 1, h}, CellWindow{w - 1, 0, 1, h}}) {
      for (const double height : {0.0, f.maxHeight, f.minHeight}) {
        const LocalFrame edge = windowFrame(basis_, rim, std::vector<double>(rim.cellCount(), height),
                                            std::vector<std::uint8_t>(rim.cellCount(), 1));
        for (std::size_t i = 0; i < rim.cellCount(); ++i) {
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

namespace {

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

std::uint64_t ShadowTiles::bytesPerWindowCell() { return bytesPerWindowCell({}); }

// How much more a light below the horizon takes (its rays' strips cross every triangle facing
// away, which is most of them): 0 at the horizon and above, 1 below it. Measured on the Rainier
// tile: already some 25 bytes a cell more at 1.3 to 2.6 degrees below (the Sun before sunrise),
// up to 34 at 20 degrees below and beyond; so no ramp, the whole of it from the horizon down.
double belowShare(const std::vector<Eigen::Vector3d>& lights) {
  double share = lights.empty() ? 1.0 : 0.0;
  for (const Eigen::Vector3d& l : lights) share = std::max(share, l.z() < 0 ? 1.0 : 0.0);
  return share;
}

std::uint64_t ShadowTiles::bytesPerWindowCell(const std::vector<Eigen::Vector3d>& lights) {
  // A window's frame at the mask's peak: vertices (24), validity and light (2), the triangles'
  // corners (24) and facing (2), the strips (24 a triangle entry, up to about 2 entries a cell at
  // a low sun), the cell order (8); before them, the heights read and filled. Measured on the
  // Rainier DEM (bench/shadow_memory.sh: single tiles of 16 to 1024 cells from a state, peak RSS
  // less the process's, over the window's planned cells): 92 to 101 bytes at altitudes 30 and
  // 60, 129 to 138 at 10, 142 to 144 at 5, 149 to 155 at 2; taken with a tenth more.
  // Below the horizon (a tile whose cells still see the Sun): up to 40 more (measured: whole
  // rasters take up to 34 more at 20 degrees below and beyond).
  return static_cast<std::uint64_t>(std::ceil(105 + 66 * lowLightShare(lights) + 40 * belowShare(lights)));
}

std::uint64_t ShadowTiles::bytesPerWholeCell(const std::vector<Eigen::Vector3d>& lights) {
  // The whole raster in memory (loadDem's mesh, then the frame and the mask): measured on the
  // Rainier DEM 128 to 134 bytes a cell at altitudes 30 and 60, 157 at 10, 171 at 5, 184 at 2
  // (peak RSS less the process's); taken with a tenth more.
  // Below the horizon: up to 40 more (250 a cell measured at 45 degrees below on Rainier).
  return static_cast<std::uint64_t>(std::ceil(150 + 66 * lowLightShare(lights) + 40 * belowShare(lights)));
}

std::array<int, 4> ShadowTiles::halo(const CellWindow& tile, const std::vector<Eigen::Vector3d>& lights,
                                     double tileLowest) const {
  std::array<int, 4> out = reach(tile, lights, tileLowest);
  out[0] = std::min(out[0], tile.col), out[1] = std::min(out[1], basis_.raster.width - tile.col - tile.width);
  out[2] = std::min(out[2], tile.row), out[3] = std::min(out[3], basis_.raster.height - tile.row - tile.height);
  return out;
}

std::array<int, 4> ShadowTiles::reach(const CellWindow& tile, const std::vector<Eigen::Vector3d>& lights,
                                      double tileLowest) const {
  std::array<int, 4> out{0, 0, 0, 0};
  const LocalFrame& f = basis_.shared;
  const Local here = localAt(basis_, tile.col + tile.width / 2, tile.row + tile.height / 2);
  // Above the tile centre's tangent plane (see the header).
  const double top = f.body.ellipsoid ? std::max(f.maxHeight, 0.0) : f.maxHeight;
  // On an ellipsoid (see the header): the ball of radius rM + top that holds all terrain, the
  // tile's cells within d of its centre cell across, and the slack below which every cell's ray
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
      if (!(rise > 0)) continue;  // a flat frame's cells are all in shadow: nothing to reach
      reach = std::max(0.0, top - tileLowest) / rise;
    } else {
      // Below every cell's horizon by more than the dip: every ray enters the body, which shades
      // the cell whatever the terrain (sunCanLight's argument, for the tile).
      if (rise <= -std::sin(slack)) continue;
      // The ray leaves the ball B(O - rM up, rM + top) after at most t = -q + sqrt(q^2 + k), for
      // q >= -d + (rM + z) rise (its cell at height z in [lowest, top] above the tangent plane,
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
  for (int& s : out) s += kHaloCells;
  return out;
}

CellWindow ShadowTiles::windowOf(const CellWindow& tile, const std::array<int, 4>& h) const {
  return {tile.col - h[0], tile.row - h[2], tile.width + h[0] + h[1], tile.height + h[2] + h[3]};
}

int ShadowTiles::tileSideFor(std::uint64_t bytes, const std::vector<Eigen::Vector3d>& lights, int multiple) const {
  const int w = basis_.raster.width, h = basis_.raster.height;
  const std::uint64_t most = bytes / bytesPerWindowCell(lights);
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

namespace {

// Whether the fill over `fill` (levels from fillVoids) is the whole raster's at every void cell of
// `region` (inside `fill`): each has twice its level of room to the fill's sides inside the raster.
bool filledAsWhole(const CellWindow& fill, const std::vector<std::uint8_t>& valid,
                   const std::vector<std::uint32_t>& levels, const CellWindow& region, int rasterWidth,
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

// The part `inner` of a window's cells.
template <class T>
std::vector<T> crop(const std::vector<T>& all, const CellWindow& outer, const CellWindow& inner) {
  std::vector<T> out(inner.cellCount());
  for (int r = 0; r < inner.height; ++r) {
    const std::size_t from =
        static_cast<std::size_t>(r + inner.row - outer.row) * outer.width + (inner.col - outer.col);
    std::copy_n(all.begin() + static_cast<std::ptrdiff_t>(from), inner.width,
                out.begin() + static_cast<std::ptrdiff_t>(r) * inner.width);
  }
  return out;
}

}  // namespace

void ShadowTiles::readFilled(const CellWindow& window, std::vector<double>& heights, std::vector<std::uint8_t>& valid,
                             std::uint64_t bytes) const {
  if (!source_) throw Error(basis_.raster.path + ": tiles restored from a state read no heights; give them");
  const int rw = basis_.raster.width, rh = basis_.raster.height;
  std::vector<double> z;
  std::vector<std::uint8_t> ok;
  std::vector<std::uint32_t> levels;
  for (int margin = 16;; margin *= 2) {
    const CellWindow fill{std::max(0, window.col - margin), std::max(0, window.row - margin),
                          std::min(rw, window.col + window.width + margin) - std::max(0, window.col - margin),
                          std::min(rh, window.row + window.height + margin) - std::max(0, window.row - margin)};
    if (bytes && fill.cellCount() * 16 > bytes) {
      throw Error(basis_.raster.path + ": a void (cells without data) around cells " + cells(window) +
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

double ShadowTiles::lowestOf(const CellWindow& tile, std::vector<double> z,
                             const std::vector<std::uint8_t>& valid) const {
  if (std::find(valid.begin(), valid.end(), 1) == valid.end()) return INFINITY;
  const Local here = localAt(basis_, tile.col + tile.width / 2, tile.row + tile.height / 2);
  fillVoids(z, tile.width, tile.height);  // positions only: the valid cells' do not depend on it
  const LocalFrame alone = windowFrame(basis_, tile, std::move(z), valid);
  double lowest = INFINITY;
  for (std::size_t i = 0; i < tile.cellCount(); ++i) {
    if (valid[i]) lowest = std::min(lowest, (alone.mesh.vertices[i] - here.origin).dot(here.up));
  }
  return lowest;
}

double ShadowTiles::lowestIn(const CellWindow& tile) const {
  if (!source_) throw Error(basis_.raster.path + ": tiles restored from a state read no heights; give them");
  std::vector<double> z;
  std::vector<std::uint8_t> valid;
  source_->read(tile, z, &blocks_, basis_.raster.path);
  heightsInMetres(basis_, tile, z, valid);
  return lowestOf(tile, std::move(z), valid);
}

LocalFrame ShadowTiles::frameOver(const CellWindow& tile, const CellWindow& window, std::uint64_t bytes,
                                  const std::vector<Eigen::Vector3d>& lights) const {
  if (bytes && window.cellCount() * bytesPerWindowCell(lights) > bytes) {
    throw Error(basis_.raster.path + ": cells " + cells(tile) + " need a window of " + cells(window) + " (" +
                memory::gib(window.cellCount() * bytesPerWindowCell(lights)) +
                ") to hold every triangle that can shade them, over the " + memory::gib(bytes) +
                " allowed; use smaller tiles or allow more memory");
  }
  std::vector<double> z;
  std::vector<std::uint8_t> valid;
  readFilled(window, z, valid, bytes);
  return windowFrame(basis_, window, std::move(z), std::move(valid));
}

LocalFrame ShadowTiles::windowOfTile(const CellWindow& tile, const std::vector<Eigen::Vector3d>& lights,
                                     std::uint64_t bytes, CellWindow& window) const {
  const double lowest = lowestIn(tile);
  if (!std::isfinite(lowest)) {  // no data: nothing to test
    window = tile;
    return {};
  }
  window = windowOf(tile, halo(tile, lights, lowest));
  return frameOver(tile, window, bytes, lights);
}

LocalFrame ShadowTiles::givenWindow(const CellWindow& given, std::vector<double> z, const CellWindow& tile,
                                    const std::vector<Eigen::Vector3d>& lights) const {
  const int rw = basis_.raster.width, rh = basis_.raster.height;
  const auto inside = [](const CellWindow& in, const CellWindow& out) {
    return in.col >= out.col && in.row >= out.row && in.col + in.width <= out.col + out.width &&
           in.row + in.height <= out.row + out.height;
  };
  if (given.col < 0 || given.row < 0 || given.col + given.width > rw || given.row + given.height > rh ||
      z.size() != given.cellCount() || !inside(tile, given) || tile.width < 1 || tile.height < 1) {
    throw Error(basis_.raster.path + ": heights of cells " + cells(given) + " (" + std::to_string(z.size()) +
                " given) for the tile " + cells(tile) + ": not on the raster or not around the tile");
  }
  if (!blocks_.aligned(given)) {
    throw Error(basis_.raster.path + ": heights of cells " + cells(given) + " given: not whole hash blocks of " +
                std::to_string(blocks_.side()) + " cells, so they cannot be checked (give checkableWindow's " +
                cells(blocks_.alignedOut(given)) + ")");
  }
  blocks_.check(given, z, basis_.raster.path);
  std::vector<std::uint8_t> valid;
  heightsInMetres(basis_, given, z, valid);
  const double lowest = lowestOf(tile, crop(z, given, tile), crop(valid, given, tile));
  if (!std::isfinite(lowest)) return {};
  const CellWindow window = windowOf(tile, halo(tile, lights, lowest));
  if (!inside(window, given)) {
    throw Error(basis_.raster.path + ": the tile " + cells(tile) + " needs the cells " + cells(window) +
                " around it (its halo), but only " + cells(given) + " are given; give a larger overlap (haloFor)");
  }
  std::vector<std::uint32_t> levels;
  fillVoids(z, given.width, given.height, &levels);
  if (!filledAsWhole(given, valid, levels, window, rw, rh)) {
    throw Error(basis_.raster.path + ": a void (cells without data) near the tile " + cells(tile) +
                " is too wide to fill the same way as over the whole raster from the cells " + cells(given) +
                "; give a larger overlap or fill the voids first (gdal_fillnodata)");
  }
  return windowFrame(basis_, window, crop(z, given, window), crop(valid, given, window));
}

namespace {

std::vector<Light> tileMask(const LocalFrame& frame, const CellWindow& tile, const Eigen::Vector3d& light,
                            const IndexOptions& options, unsigned threads, ShadowSearch search) {
  if (frame.cellCount() == 0) return std::vector<Light>(tile.cellCount(), Light::NoData);
  const CellWindow& window = frame.window;
  const CellWindow inside{tile.col - window.col, tile.row - window.row, tile.width, tile.height};
  return crop(shadowMask(frame, light, options, {}, threads, search, inside),
              CellWindow{0, 0, window.width, window.height}, inside);
}

}  // namespace

std::vector<Light> ShadowTiles::mask(const CellWindow& tile, const Eigen::Vector3d& light, const IndexOptions& options,
                                     unsigned threads, ShadowSearch search, std::uint64_t bytes) const {
  CellWindow window;
  return tileMask(windowOfTile(tile, {light}, bytes, window), tile, light, options, threads, search);
}

std::vector<Light> ShadowTiles::maskFromHeights(const CellWindow& window, std::vector<double> heights,
                                                const CellWindow& tile, const Eigen::Vector3d& light,
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

SunlightHours ShadowTiles::tileHours(const LocalFrame& frame, const CellWindow& tile, double startJulianDay,
                                     double endJulianDay, double stepHours, const IndexOptions& options,
                                     ShadowSearch search, unsigned threads) const {
  if (frame.cellCount() == 0) {  // no data: no hours (sunlightHours's zeros), its steps counted alike
    SunlightHours none;
    none.elapsedHours = (endJulianDay - startJulianDay) * 24.0;
    none.steps = static_cast<int>(qota::sunlightSteps(startJulianDay, endJulianDay, stepHours).size());
    none.hours.assign(tile.cellCount(), 0.0);
    none.valid.assign(tile.cellCount(), 0);
    return none;
  }
  // Every step the window's own sunlightHours computes is among the halo's lights when its slack
  // is within the bound they were chosen with.
  if (frame.body.ellipsoid && frame.horizonSlack() > slack_ + 1e-9) {
    throw Error(basis_.raster.path + ": the horizon slack of cells " + cells(frame.window) +
                " exceeds the raster's bound");
  }
  const CellWindow& window = frame.window;
  const CellWindow inside{tile.col - window.col, tile.row - window.row, tile.width, tile.height};
  SunlightHours all = sunlightHours(frame, basis_.raster.path, startJulianDay, endJulianDay, stepHours, options, {},
                                    search, inside, threads);
  all.hours = crop(all.hours, CellWindow{0, 0, window.width, window.height}, inside);
  all.valid = crop(frame.valid, CellWindow{0, 0, window.width, window.height}, inside);
  return all;
}

SunlightHours ShadowTiles::hours(const CellWindow& tile, double startJulianDay, double endJulianDay, double stepHours,
                                 const IndexOptions& options, ShadowSearch search, std::uint64_t bytes,
                                 unsigned threads) const {
  const double lowest = lowestIn(tile);
  if (!std::isfinite(lowest))
    return tileHours(LocalFrame{}, tile, startJulianDay, endJulianDay, stepHours, options, search, threads);
  // A low sun's halo is long, a high sun's short: a window for every light of the day would be a
  // sunrise's for the noon steps too. So the steps whose own window is at most twice the smallest
  // share one window, the others (the low suns) another, loaded as the steps come, in order; the
  // lit cells are summed in step order, as sunlightHours sums them.
  const std::vector<SunlightStep> steps = qota::sunlightSteps(startJulianDay, endJulianDay, stepHours);
  const LocalFrame& f = basis_.shared;
  std::vector<int> group(steps.size(), -1);  // -1: night over the whole raster (skipped there too)
  std::vector<Eigen::Vector3d> stepLight(steps.size());
  std::vector<std::uint64_t> windowCells(steps.size(), 0);
  std::uint64_t smallest = ~std::uint64_t{0};
  for (std::size_t k = 0; k < steps.size(); ++k) {
    const SunPosition sun = sunOverFrame(f, steps[k].middleJulianDay, basis_.raster.path);
    if (!sunCanLight(f, sun, slack_)) continue;
    stepLight[k] = f.towardSun(sun);
    windowCells[k] = windowOf(tile, halo(tile, {stepLight[k]}, lowest)).cellCount();
    smallest = std::min(smallest, windowCells[k]);
    group[k] = 0;
  }
  std::vector<Eigen::Vector3d> groupLights[2];
  for (std::size_t k = 0; k < steps.size(); ++k) {
    if (group[k] < 0) continue;
    group[k] = windowCells[k] <= 2 * smallest ? 0 : 1;
    groupLights[group[k]].push_back(stepLight[k]);
  }
  SunlightHours out;
  out.elapsedHours = (endJulianDay - startJulianDay) * 24.0;
  out.steps = static_cast<int>(steps.size());
  out.hours.assign(tile.cellCount(), 0.0);
  LocalFrame frame;
  int loaded = -1;
  double frameSlack = 0;
  CellWindow inside;
  const auto load = [&](int g) {
    frame = frameOver(tile, windowOf(tile, halo(tile, groupLights[g], lowest)), bytes, groupLights[g]);
    // Every step the window computes is among its lights when its slack is within the bound
    // they were chosen with (sunlightHours's skip, for the window).
    if (frame.body.ellipsoid && frame.horizonSlack() > slack_ + 1e-9) {
      throw Error(basis_.raster.path + ": the horizon slack of cells " + cells(frame.window) +
                  " exceeds the raster's bound");
    }
    frameSlack = frame.horizonSlack();
    inside = CellWindow{tile.col - frame.window.col, tile.row - frame.window.row, tile.width, tile.height};
    if (out.valid.empty())
      out.valid = crop(frame.valid, CellWindow{0, 0, frame.window.width, frame.window.height}, inside);
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

SunlightHours ShadowTiles::hoursFromHeights(const CellWindow& window, std::vector<double> heights,
                                            const CellWindow& tile, double startJulianDay, double endJulianDay,
                                            double stepHours, const std::vector<Eigen::Vector3d>& lights,
                                            const IndexOptions& options, ShadowSearch search, unsigned threads) const {
  return tileHours(givenWindow(window, std::move(heights), tile, lights), tile, startJulianDay, endJulianDay, stepHours,
                   options, search, threads);
}

std::array<int, 4> ShadowTiles::haloFor(int tileWidth, int tileHeight,
                                        const std::vector<Eigen::Vector3d>& lights) const {
  return haloAtMost(tileWidth, tileHeight, lights, basis_.shared.minHeight);
}

std::uint64_t ShadowTiles::largestWindowCells(const std::vector<CellWindow>& tiles,
                                              const std::vector<Eigen::Vector3d>& lights) const {
  const LocalFrame& f = basis_.shared;
  const int rw = basis_.raster.width, rh = basis_.raster.height;
  int tw = 1, th = 1;
  for (const CellWindow& t : tiles) tw = std::max(tw, t.width), th = std::max(th, t.height);
  // The halo falls as a tile's lowest cell rises: tiles take the halo of the level at or below
  // their bound, one of kLevels between the raster's lowest and highest (a few dozen halos for any
  // number of tiles).
  constexpr int kLevels = 32;
  const double lo = std::isfinite(f.minHeight) ? f.minHeight : 0, hi = std::isfinite(f.maxHeight) ? f.maxHeight : lo;
  std::vector<std::optional<std::array<int, 4>>> halos(kLevels + 1);
  const double metres = f.metresPerUnit;
  std::uint64_t most = 0;
  for (const CellWindow& t : tiles) {
    const auto [low, high] = blocks_.rangeOver(t);
    // The tile's lowest, at least (over the ellipsoid: with the geoid's least undulation).
    const double bound = (metres >= 0 ? low * metres : high * metres) + basis_.geoidLow;
    if (!std::isfinite(bound) && bound > 0) {  // no data: no window beyond the tile
      most = std::max<std::uint64_t>(most, t.cellCount());
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
    const CellWindow tile{static_cast<int>(c * (w - tw)), static_cast<int>(r * (h - th)), tw, th};
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

namespace {

// state()'s text: a first line naming the format, then one "name value" a line; numbers in
// hexadecimal floating point (every bit), text as its length and its bytes; last, "checksum" and
// checksumOf everything before that line, so that an edit or damage anywhere is refused.
constexpr const char* kStateMagic = "qota-shadow-tiles";
constexpr int kStateFormat = 2;

struct StateWriter {
  std::ostringstream out;
  void number(const char* name, double v) {
    char buffer[64];
    const auto end = std::to_chars(buffer, buffer + sizeof buffer, v, std::chars_format::hex).ptr;
    out << name << ' ' << std::string(buffer, end) << '\n';
  }
  void text(const char* name, const std::string& v) { out << name << ' ' << v.size() << ' ' << v << '\n'; }
  std::string finish() {
    std::string body = out.str();
    return body + "checksum " + checksumOf(body) + "\n";
  }
};

struct StateReader {
  std::istringstream in;
  [[noreturn]] static void refuse(const std::string& why) { throw Error("a shadow tiles state " + why); }
  void expect(const char* name) {
    std::string got;
    if (!(in >> got) || got != name) refuse(std::string("without its '") + name + "'");
    in.get();
  }
  double number(const char* name) {
    expect(name);
    std::string word;
    in >> word;
    double v = 0;
    const auto [end, ec] = std::from_chars(word.data(), word.data() + word.size(), v, std::chars_format::hex);
    if (ec != std::errc() || end != word.data() + word.size())
      refuse(std::string("with '") + name + "' not a number: " + word);
    return v;
  }
  // A number that must be finite and in [lo, hi] (and whole, when asked).
  double bounded(const char* name, double lo, double hi, bool whole = false) {
    const double v = number(name);
    if (!(v >= lo && v <= hi) || (whole && v != std::floor(v))) {
      refuse(std::string("with '") + name + "' " + std::to_string(v) + ", which no raster gives");
    }
    return v;
  }
  std::string text(const char* name) {
    expect(name);
    std::size_t n = 0;
    if (!(in >> n) || n > ShadowTiles::kMostStateBytes) refuse(std::string("with a bad '") + name + "'");
    in.get();
    std::string v(n, '\0');
    if (!in.read(v.data(), static_cast<std::streamsize>(n))) refuse(std::string("cut in '") + name + "'");
    return v;
  }
};

// The state's text without its checksum line, once that checksum is checked.
std::string checkedStateBody(const std::string& state) {
  const std::string magic = std::string(kStateMagic) + " ";
  if (state.compare(0, magic.size(), magic) != 0)
    throw Error("not a shadow tiles state (no '" + std::string(kStateMagic) + "' line)");
  const std::size_t line = state.rfind("\nchecksum ");
  if (line == std::string::npos) {
    if (state.compare(0, magic.size() + 2, magic + "1\n") == 0) {
      throw Error("a shadow tiles state of an older qota (no checksum); make it again");
    }
    throw Error("a shadow tiles state that was edited, damaged or cut short (no checksum line); make it again");
  }
  const std::string body = state.substr(0, line + 1);
  std::string sum = state.substr(line + 10);
  if (!sum.empty() && sum.back() == '\n') sum.pop_back();
  if (sum != checksumOf(body)) {
    throw Error(
        "a shadow tiles state that was edited or damaged (its checksum does not match its text); make it again");
  }
  return body;
}

std::string shortest(double v) {
  char buffer[64];
  return std::string(buffer, std::to_chars(buffer, buffer + sizeof buffer, v).ptr);
}

std::string nodataText(const std::optional<double>& nodata) {
  if (!nodata) return "none";
  char buffer[64];
  return std::string(buffer, std::to_chars(buffer, buffer + sizeof buffer, *nodata, std::chars_format::hex).ptr);
}

}  // namespace

std::string ShadowTiles::state() const {
  StateWriter w;
  w.out << kStateMagic << ' ' << kStateFormat << '\n';
  const DemTerrain& d = basis_.raster;
  const LocalFrame& f = basis_.shared;
  w.text("qota", QOTA_VERSION_STRING);
  w.text("path", d.path);
  w.number("width", d.width), w.number("height", d.height);
  for (double g : d.geotransform) w.number("gt", g);
  w.text("crs", d.crsWkt);
  w.number("band", d.band);
  w.text("nodata", nodataText(d.nodata));
  w.text("unit", d.verticalUnit.name);
  w.number("metresPerUnit", d.verticalUnit.metresPerUnit);
  w.number("flat", basis_.options.flat), w.number("pixelSize", basis_.options.pixelSize);
  w.number("zFactor", basis_.options.zFactor), w.number("scale", basis_.options.scale);
  w.text("heightRefAsked", basis_.options.heightRef);
  w.text("verticalCrs", d.verticalReference.name);
  w.number("verticalEpsg", d.verticalReference.epsg);
  w.number("verticalEllipsoidal", d.verticalReference.ellipsoidal), w.number("earth", d.verticalReference.earth);
  w.text("heightRef", basis_.heightRef.name);
  w.number("minHeight", f.minHeight), w.number("maxHeight", f.maxHeight);
  w.number("pixelSizeX", f.pixelSizeX), w.number("pixelSizeY", f.pixelSizeY);
  w.number("lowest", f.body.lowest), w.number("winding", f.gridWinding);
  w.number("slack", slack_), w.number("validCells", static_cast<double>(validCells_));
  w.number("blockSide", blocks_.side());
  std::string hashes;
  hashes.reserve(blocks_.hashes().size() * 16);
  for (std::uint64_t h : blocks_.hashes()) hashes += hexOf(h);
  w.text("blocks", hashes);
  // The blocks' height ranges (in the raster's unit): what plans a tile's window before reading it.
  const auto numbers = [](const std::vector<double>& values) {
    std::string out;
    char buffer[64];
    for (double v : values) {
      out.append(buffer, std::to_chars(buffer, buffer + sizeof buffer, v, std::chars_format::hex).ptr);
      out += ' ';
    }
    return out;
  };
  w.text("blockLows", numbers(blocks_.lows()));
  w.text("blockHighs", numbers(blocks_.highs()));
  return w.finish();
}

ShadowTiles ShadowTiles::restore(const std::string& state) {
  if (state.size() > kMostStateBytes)
    throw Error("a shadow tiles state of " + std::to_string(state.size()) + " bytes: larger than any");
  StateReader r{std::istringstream(checkedStateBody(state))};
  std::string magic;
  int format = 0;
  if (!(r.in >> magic >> format) || magic != kStateMagic || format != kStateFormat) {
    throw Error("a shadow tiles state of another format (" + std::to_string(format) + ", this qota reads " +
                std::to_string(kStateFormat) + "); make it again");
  }
  const std::string version = r.text("qota");
  if (version != QOTA_VERSION_STRING) {
    throw Error("a shadow tiles state made by qota " + version + ", not this qota " + QOTA_VERSION_STRING +
                "; make it again");
  }
  constexpr double kInt = 2147483647.0;
  DemTerrain d;
  d.path = r.text("path");
  d.width = static_cast<int>(r.bounded("width", 1, kInt, true));
  d.height = static_cast<int>(r.bounded("height", 1, kInt, true));
  for (double& g : d.geotransform) g = r.bounded("gt", -1e300, 1e300);
  const auto& g = d.geotransform;
  if (!(g[1] * g[5] - g[2] * g[4] != 0)) StateReader::refuse("with a geotransform without area");
  d.crsWkt = r.text("crs");
  d.band = static_cast<int>(r.bounded("band", 1, kInt, true));
  const std::string nodata = r.text("nodata");
  if (nodata != "none") {
    double v = 0;
    const auto [end, ec] = std::from_chars(nodata.data(), nodata.data() + nodata.size(), v, std::chars_format::hex);
    if (ec != std::errc() || end != nodata.data() + nodata.size())
      StateReader::refuse("with a nodata value that is not a number");
    d.nodata = v;
  }
  d.verticalUnit.name = r.text("unit");
  d.verticalUnit.metresPerUnit = r.bounded("metresPerUnit", 1e-12, 1e12);
  FrameOptions o;
  o.flat = r.bounded("flat", 0, 1, true) != 0;
  o.pixelSize = r.bounded("pixelSize", 0, 1e300);
  o.zFactor = r.bounded("zFactor", -1e300, 1e300), o.scale = r.bounded("scale", 0, 1e300);
  o.heightRef = r.text("heightRefAsked");
  d.verticalReference.name = r.text("verticalCrs");
  d.verticalReference.epsg = static_cast<int>(r.bounded("verticalEpsg", 0, kInt, true));
  d.verticalReference.ellipsoidal = r.bounded("verticalEllipsoidal", 0, 1, true) != 0;
  d.verticalReference.earth = r.bounded("earth", 0, 1, true) != 0;
  const std::string heightRef = r.text("heightRef");
  ShadowTiles t;
  t.basis_ = frameBasis(d, o);
  if (t.basis_.heightRef.name != heightRef) {
    throw Error("a shadow tiles state made over the " + heightRef + ", which is the " + t.basis_.heightRef.name +
                " here; make it again");
  }
  LocalFrame& f = t.basis_.shared;
  f.minHeight = r.number("minHeight"), f.maxHeight = r.number("maxHeight");
  f.pixelSizeX = r.bounded("pixelSizeX", 1e-300, 1e300), f.pixelSizeY = r.bounded("pixelSizeY", 1e-300, 1e300);
  f.body.lowest = r.bounded("lowest", -1e300, 1e300);
  f.gridWinding = static_cast<int>(r.bounded("winding", -1, 1, true));
  t.slack_ = r.bounded("slack", 0, 360);
  const double cells = static_cast<double>(d.width) * d.height;
  t.validCells_ = static_cast<std::uint64_t>(r.bounded("validCells", 0, cells, true));
  // The height range: finite and in order when the raster has data (the pass's +inf/-inf else).
  if (f.gridWinding == 0 || (t.validCells_ > 0 && !(std::isfinite(f.minHeight) && std::isfinite(f.maxHeight) &&
                                                    f.minHeight <= f.maxHeight))) {
    StateReader::refuse("with a height range or winding that no raster gives");
  }
  const int side = static_cast<int>(r.bounded("blockSide", 64, kInt, true));
  const std::string hex = r.text("blocks");
  if (hex.size() % 16 != 0) StateReader::refuse("with a cut block hash");
  std::vector<std::uint64_t> hashes(hex.size() / 16);
  for (std::size_t k = 0; k < hashes.size(); ++k) {
    const char* first = hex.data() + 16 * k;
    const auto [end, ec] = std::from_chars(first, first + 16, hashes[k], 16);
    if (ec != std::errc() || end != first + 16) StateReader::refuse("with a block hash that is not hexadecimal");
  }
  try {
    t.blocks_ = HeightBlocks(d.width, d.height, side, std::move(hashes));
  } catch (const Error& e) {
    StateReader::refuse(std::string("with ") + e.what());
  }
  if (t.blocks_.side() != HeightBlocks(d.width, d.height).side()) StateReader::refuse("with blocks of another size");
  const auto numbers = [](const std::string& text) {
    std::vector<double> out;
    const char* p = text.data();
    const char* end = p + text.size();
    while (p < end) {
      double v = 0;
      const auto [next, ec] = std::from_chars(p, end, v, std::chars_format::hex);
      if (ec != std::errc() || next == end || *next != ' ')
        StateReader::refuse("with a block height range that is not numbers");
      out.push_back(v);
      p = next + 1;
    }
    return out;
  };
  std::vector<double> lows = numbers(r.text("blockLows"));  // (in this order: the text's)
  std::vector<double> highs = numbers(r.text("blockHighs"));
  try {
    t.blocks_.setRanges(std::move(lows), std::move(highs));
  } catch (const Error& e) {
    StateReader::refuse(std::string("with ") + e.what());
  }
  t.basis_.complete = true;
  return t;
}

ShadowTiles ShadowTiles::restore(const std::string& state, const std::string& path, const DemOptions& dem,
                                 const FrameOptions& frame) {
  ShadowTiles t = restore(state);
  auto source = std::make_unique<Source>();
  source->windows = std::make_unique<DemWindows>(path, dem);
  const DemWindows* windows = source->windows.get();
  const DemTerrain& d = windows->dem();
  const DemTerrain& was = t.basis_.raster;
  const FrameOptions& o = t.basis_.options;
  const auto refuse = [&](const std::string& field, const std::string& state, const std::string& now) {
    throw Error(path + ": not the raster of the shadow tiles' state (made from " + was.path + "): its " + field +
                " differs (the state's " + state + ", this raster's " + now + ")");
  };
  const auto size = [](const DemTerrain& r) { return std::to_string(r.width) + " x " + std::to_string(r.height); };
  const auto gt = [](const DemTerrain& r) {
    std::string out;
    for (double v : r.geotransform) out += (out.empty() ? "" : ",") + shortest(v);
    return out;
  };
  const auto nodata = [](const DemTerrain& r) { return r.nodata ? shortest(*r.nodata) : std::string("none"); };
  if (d.width != was.width || d.height != was.height) refuse("size", size(was), size(d));
  if (d.geotransform != was.geotransform) refuse("geotransform", gt(was), gt(d));
  if (d.crsWkt != was.crsWkt)
    refuse("CRS", "'" + was.crsWkt.substr(0, 60) + "...'", "'" + d.crsWkt.substr(0, 60) + "...'");
  if (d.band != was.band) refuse("band", std::to_string(was.band), std::to_string(d.band));
  if (d.nodata.has_value() != was.nodata.has_value() ||
      (d.nodata && !(*d.nodata == *was.nodata || (std::isnan(*d.nodata) && std::isnan(*was.nodata))))) {
    refuse("nodata value", nodata(was), nodata(d));
  }
  if (d.verticalUnit.name != was.verticalUnit.name || d.verticalUnit.metresPerUnit != was.verticalUnit.metresPerUnit) {
    refuse("vertical unit", "'" + was.verticalUnit.name + "'", "'" + d.verticalUnit.name + "'");
  }
  const auto option = [&](const char* name, double state, double now) {
    if (state != now) {
      throw Error(path + ": the shadow tiles' state was made with other frame options (" + name + " " +
                  shortest(state) + ", this run " + shortest(now) + "); give the same, or another state file");
    }
  };
  option("--flat", o.flat, frame.flat);
  option("--pixel-size", o.pixelSize, frame.pixelSize);
  option("-z", o.zFactor, frame.zFactor);
  option("-s", o.scale, frame.scale);
  if (frame.heightRef != o.heightRef) {
    throw Error(path + ": the shadow tiles' state was made with other frame options (--height-ref '" + o.heightRef +
                "', this run '" + frame.heightRef + "'); give the same, or another state file");
  }
  if (d.verticalReference.name != was.verticalReference.name ||
      d.verticalReference.epsg != was.verticalReference.epsg ||
      d.verticalReference.ellipsoidal != was.verticalReference.ellipsoidal) {
    refuse("vertical CRS", "'" + was.verticalReference.name + "'", "'" + d.verticalReference.name + "'");
  }
  source->reader = [windows](const CellWindow& w, std::vector<double>& out) {
    windows->read(w.col, w.row, w.width, w.height, out);
  };
  t.source_ = std::move(source);
  t.basis_.raster.path = d.path;
  return t;
}

}  // namespace qota
