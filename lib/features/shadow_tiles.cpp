// Shadows of a raster tile by tile (see qota/shadow_tiles.hpp for why each tile is exact).
#include "qota/shadow_tiles.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <mutex>

#include "qota/error.hpp"
#include "qota/memory_budget.hpp"

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

struct ShadowTiles::Open {
  explicit Open(const std::string& path, const DemOptions& options) : windows(path, options) {}
  DemWindows windows;
  mutable std::mutex lock;  // one read at a time
  void read(const CellWindow& w, std::vector<double>& out) const {
    const std::lock_guard<std::mutex> guard(lock);
    windows.read(w.col, w.row, w.width, w.height, out);
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
                         const Progress& progress)
    : open_(std::make_unique<Open>(path, demOptions)) {
  basis_ = frameBasis(open_->windows.dem(), frameOptions);
  const int w = basis_.raster.width, h = basis_.raster.height;
  const RasterGrid::Closure& closure = basis_.closure;
  if (closure.wrapsColumns || closure.northCap || closure.southCap) {
    throw Error(path + ": the raster is closed round the globe, so it is shadowed whole, not by tiles");
  }
  // The height range: one pass by rows, a few million cells at a time.
  double lo = INFINITY, hi = -INFINITY;
  const int rowsAtOnce = static_cast<int>(std::clamp<std::int64_t>((4 << 20) / std::max(1, w), 1, h));
  std::vector<double> z;
  std::vector<std::uint8_t> valid;
  for (int r = 0; r < h; r += rowsAtOnce) {
    const CellWindow rows{0, r, w, std::min(rowsAtOnce, h - r)};
    open_->read(rows, z);
    heightsInMetres(basis_, rows, z, valid);
    for (std::size_t i = 0; i < z.size(); ++i) {
      if (valid[i]) lo = std::min(lo, z[i]), hi = std::max(hi, z[i]), ++validCells_;
    }
    if (progress && !progress(static_cast<double>(r + rows.height) / h, "reading the height range")) {
      throw Error("shadow computation cancelled");
    }
  }
  // The centre square, for the pixel size and the triangles' turn.
  const CellWindow centre{std::max(0, (w - 1) / 2), std::max(0, (h - 1) / 2), std::min(2, w), std::min(2, h)};
  readFilled(centre, z, valid, 0);
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
    for (const CellWindow& rim : {CellWindow{0, 0, w, 1}, CellWindow{0, h - 1, w, 1}, CellWindow{0, 0, 1, h},
                                  CellWindow{w - 1, 0, 1, h}}) {
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

const DemTerrain& ShadowTiles::dem() const { return open_->windows.dem(); }

std::uint64_t ShadowTiles::bytesPerWindowCell() {
  // A window's frame at the mask's peak: vertices (24), validity and light (2), the triangles'
  // corners (24) and facing (2), the strips (24 a triangle entry, up to about 2 entries a cell
  // at a low sun), the cell order (8); and the heights read and filled before (8 + 4 + 1 over a
  // window that may be a little larger). Measured (scripts in bench/shadow_tiles.sh) up to 150;
  // with a margin.
  return 200;
}

std::array<int, 4> ShadowTiles::halo(const CellWindow& tile, const std::vector<Eigen::Vector3d>& lights,
                                     double tileLowest) const {
  std::array<int, 4> out{0, 0, 0, 0};
  const LocalFrame& f = basis_.shared;
  const Local here = localAt(basis_, tile.col + tile.width / 2, tile.row + tile.height / 2);
  // Above the tile centre's tangent plane (see the header).
  const double top = f.body.ellipsoid ? std::max(f.maxHeight, 0.0) : f.maxHeight;
  for (const Eigen::Vector3d& light0 : lights) {
    const Eigen::Vector3d light = light0.normalized();
    const double rise = light.dot(here.up);
    if (!(rise > 0)) {
      if (!f.body.ellipsoid) continue;  // a flat frame's cells are all in shadow: nothing to reach
      throw Error(basis_.raster.path + ": the light is at or below the horizon at cells " + cells(tile) +
                  ", so its shadows there reach without bound; this light is shadowed on the whole raster only");
    }
    const double reach = std::max(0.0, top - tileLowest) / rise;  // along the ray
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
  out[0] = std::min(out[0], tile.col), out[1] = std::min(out[1], basis_.raster.width - tile.col - tile.width);
  out[2] = std::min(out[2], tile.row), out[3] = std::min(out[3], basis_.raster.height - tile.row - tile.height);
  return out;
}

CellWindow ShadowTiles::windowOf(const CellWindow& tile, const std::array<int, 4>& h) const {
  return {tile.col - h[0], tile.row - h[2], tile.width + h[0] + h[1], tile.height + h[2] + h[3]};
}

int ShadowTiles::tileSideFor(std::uint64_t bytes, const std::vector<Eigen::Vector3d>& lights, int multiple) const {
  const LocalFrame& f = basis_.shared;
  const int w = basis_.raster.width, h = basis_.raster.height;
  const std::uint64_t most = bytes / bytesPerWindowCell();
  // Whether tiles of `side` fit; a larger side never takes a smaller window.
  const auto fits = [&](int side) {
    // The worst window: the tile's lowest cell at the raster's lowest, less on an ellipsoid the
    // fall of the surface across the tile, at the centre and the four corners.
    std::uint64_t worst = 0;
    for (const auto& [c, r] : {std::pair{0.5, 0.5}, std::pair{0.0, 0.0}, std::pair{1.0, 0.0}, std::pair{0.0, 1.0},
                               std::pair{1.0, 1.0}}) {
      const CellWindow tile{std::clamp(static_cast<int>(c * (w - side)), 0, std::max(0, w - side)),
                            std::clamp(static_cast<int>(r * (h - side)), 0, std::max(0, h - side)), std::min(side, w),
                            std::min(side, h)};
      double lowest = f.minHeight;
      if (f.body.ellipsoid) {
        const Local l = localAt(basis_, tile.col, tile.row);
        const double across = side * (l.east.norm() + l.south.norm());
        lowest -= 1.5 * across * across / (2 * f.body.b * f.body.b / f.body.a);
      }
      worst = std::max<std::uint64_t>(worst, windowOf(tile, halo(tile, lights, lowest)).cellCount());
    }
    return worst <= most;
  };
  int lo = 0, hi = (std::max(w, h) + multiple - 1) / multiple;  // in multiples: lo fits (0: none), hi + 1 does not
  if (fits(hi * multiple)) return hi * multiple;
  while (hi - lo > 1) {
    const int mid = (lo + hi) / 2;
    (fits(mid * multiple) ? lo : hi) = mid;
  }
  return lo * multiple;
}

void ShadowTiles::readFilled(const CellWindow& window, std::vector<double>& heights, std::vector<std::uint8_t>& valid,
                             std::uint64_t bytes) const {
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
    open_->read(fill, z);
    heightsInMetres(basis_, fill, z, ok);
    fillVoids(z, fill.width, fill.height, &levels);
    // Room from a cell to the fill window's sides inside the raster (unbounded at the raster's edge).
    const int big = 1 << 30;
    bool exact = true;
    for (int r = window.row; r < window.row + window.height && exact; ++r) {
      for (int c = window.col; c < window.col + window.width; ++c) {
        const std::size_t i = static_cast<std::size_t>(r - fill.row) * fill.width + (c - fill.col);
        if (ok[i]) continue;
        const std::int64_t room = std::min({fill.col > 0 ? c - fill.col : big,
                                            fill.col + fill.width < rw ? fill.col + fill.width - 1 - c : big,
                                            fill.row > 0 ? r - fill.row : big,
                                            fill.row + fill.height < rh ? fill.row + fill.height - 1 - r : big});
        if (room < big && (levels[i] == kNeverFilled || room < 2 * static_cast<std::int64_t>(levels[i]))) {
          exact = false;
          break;
        }
      }
    }
    if (!exact) continue;
    heights.resize(window.cellCount());
    valid.resize(window.cellCount());
    for (int r = 0; r < window.height; ++r) {
      const std::size_t from = static_cast<std::size_t>(r + window.row - fill.row) * fill.width + (window.col - fill.col);
      std::copy_n(z.begin() + static_cast<std::ptrdiff_t>(from), window.width, heights.begin() + static_cast<std::ptrdiff_t>(r) * window.width);
      std::copy_n(ok.begin() + static_cast<std::ptrdiff_t>(from), window.width, valid.begin() + static_cast<std::ptrdiff_t>(r) * window.width);
    }
    return;
  }
}

LocalFrame ShadowTiles::windowOfTile(const CellWindow& tile, const std::vector<Eigen::Vector3d>& lights,
                                     std::uint64_t bytes, CellWindow& window) const {
  // The tile alone first: its lowest cell above its centre's tangent plane.
  std::vector<double> z;
  std::vector<std::uint8_t> valid;
  open_->read(tile, z);
  heightsInMetres(basis_, tile, z, valid);
  double lowest = INFINITY;
  {
    const Local here = localAt(basis_, tile.col + tile.width / 2, tile.row + tile.height / 2);
    const bool any = std::find(valid.begin(), valid.end(), 1) != valid.end();
    if (any) {
      fillVoids(z, tile.width, tile.height);  // positions only: the valid cells' do not depend on it
      const LocalFrame alone = windowFrame(basis_, tile, std::move(z), valid);
      for (std::size_t i = 0; i < tile.cellCount(); ++i) {
        if (valid[i]) lowest = std::min(lowest, (alone.mesh.vertices[i] - here.origin).dot(here.up));
      }
    }
  }
  if (!std::isfinite(lowest)) {  // no data: nothing to test
    window = tile;
    return {};
  }
  window = windowOf(tile, halo(tile, lights, lowest));
  if (bytes && window.cellCount() * bytesPerWindowCell() > bytes) {
    throw Error(basis_.raster.path + ": cells " + cells(tile) + " need a window of " + cells(window) + " (" +
                memory::gib(window.cellCount() * bytesPerWindowCell()) + ") to hold every triangle that can shade them, over the " +
                memory::gib(bytes) + " allowed; use smaller tiles or allow more memory");
  }
  readFilled(window, z, valid, bytes);
  return windowFrame(basis_, window, std::move(z), std::move(valid));
}

std::vector<Light> ShadowTiles::mask(const CellWindow& tile, const Eigen::Vector3d& light, const IndexOptions& options,
                                     unsigned threads, ShadowSearch search, std::uint64_t bytes) const {
  CellWindow window;
  const LocalFrame frame = windowOfTile(tile, {light}, bytes, window);
  std::vector<Light> out(tile.cellCount(), Light::NoData);
  if (frame.cellCount() == 0) return out;
  const CellWindow inside{tile.col - window.col, tile.row - window.row, tile.width, tile.height};
  const std::vector<Light> all = shadowMask(frame, light, options, {}, threads, search, inside);
  for (int r = 0; r < tile.height; ++r) {
    std::copy_n(all.begin() + static_cast<std::ptrdiff_t>(r + inside.row) * window.width + inside.col, tile.width,
                out.begin() + static_cast<std::ptrdiff_t>(r) * tile.width);
  }
  return out;
}

std::vector<Eigen::Vector3d> ShadowTiles::sunlightSteps(double startJulianDay, double endJulianDay, double stepHours,
                                                        double slack) const {
  std::vector<Eigen::Vector3d> out;
  const double elapsed = (endJulianDay - startJulianDay) * 24.0;
  if (!(stepHours >= 1.0 / 60) || !(stepHours <= elapsed)) return out;  // sunlightHours refuses it
  const int steps = static_cast<int>(std::ceil(elapsed / stepHours - 1e-9));
  const LocalFrame& f = basis_.shared;
  for (int k = 0; k < steps; ++k) {
    const double t0 = k * stepHours, dt = std::min(stepHours, elapsed - t0);
    const SunPosition sun = sunOverFrame(f, startJulianDay + (t0 + dt / 2) / 24.0, basis_.raster.path);
    if (sun.altitude <= -slack || (!f.body.ellipsoid && sun.altitude <= 0)) continue;
    out.push_back(f.towardSun(sun));
  }
  return out;
}

SunlightHours ShadowTiles::hours(const CellWindow& tile, double startJulianDay, double endJulianDay, double stepHours,
                                 const std::vector<Eigen::Vector3d>& lights, const IndexOptions& options,
                                 ShadowSearch search, std::uint64_t bytes) const {
  CellWindow window;
  const LocalFrame frame = windowOfTile(tile, lights, bytes, window);
  if (frame.cellCount() == 0) {  // no data: no hours (sunlightHours's zeros), its steps counted alike
    SunlightHours none;
    none.elapsedHours = (endJulianDay - startJulianDay) * 24.0;
    none.steps = static_cast<int>(std::ceil(none.elapsedHours / stepHours - 1e-9));
    none.hours.assign(tile.cellCount(), 0.0);
    return none;
  }
  // Every step the window's own sunlightHours computes is among `lights` when its slack is
  // within the bound they were chosen with.
  if (frame.horizonSlack() > slack_ + 1e-9 && frame.body.ellipsoid) {
    throw Error(basis_.raster.path + ": the horizon slack of cells " + cells(window) + " exceeds the raster's bound");
  }
  const CellWindow inside{tile.col - window.col, tile.row - window.row, tile.width, tile.height};
  SunlightHours all = sunlightHours(frame, basis_.raster.path, startJulianDay, endJulianDay, stepHours, options, {},
                                    search, inside);
  std::vector<double> out(tile.cellCount());
  for (int r = 0; r < tile.height; ++r) {
    std::copy_n(all.hours.begin() + static_cast<std::ptrdiff_t>(r + inside.row) * window.width + inside.col, tile.width,
                out.begin() + static_cast<std::ptrdiff_t>(r) * tile.width);
  }
  all.hours = std::move(out);
  return all;
}

}  // namespace qota
