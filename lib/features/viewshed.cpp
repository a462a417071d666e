#include "qota/viewshed.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>

#include "line_crossing.hpp"
#include "qota/batch.hpp"
#include "qota/error.hpp"
#include "qota/memory_budget.hpp"
#include "qota/terrain.hpp"
#include "shadow_facing.hpp"
#include "viewshed_sweep.hpp"
#include "walk_ring.hpp"

namespace qota {

namespace {

std::string number(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.10g", x);
  return buf;
}

void checkMetres(const char* name, double value) {
  if (!std::isfinite(value) || value < 0) {
    throw Error(std::string(name) + " must be a finite number of metres, 0 or more, got " + number(value));
  }
}

// A height above the surface: metres, 0 up to kMaxHeight (no terrain reaches beyond it).
void checkHeight(const std::string& name, double value) {
  if (!std::isfinite(value) || value < 0 || value > kMaxHeight) {
    throw Error(name + " must be a finite number of metres from 0 to 1e9, got " + number(value));
  }
}

// The triangulated surface's height (metres) at pixel position (col, row), by the raster rule
// (raster_grid.hpp: squares split from top-left to bottom-right; the outer half pixel flat to the
// edge), from the heights in metres; NaN over a void. A point on a square's side or corner lies in
// every triangle around it: any of them with data answers (the surface is continuous).
double surfaceAt(const std::vector<double>& z, const std::vector<std::uint8_t>& valid, int w, int h, double col,
                 double row) {
  const double c = std::clamp(col, 0.5, w - 0.5) - 0.5, r = std::clamp(row, 0.5, h - 0.5) - 0.5;
  const int cf = static_cast<int>(std::floor(c)), rf = static_cast<int>(std::floor(r));
  for (int c0 = std::min(cf, w - 2); c0 >= std::max(cf - 1, 0); --c0) {
    for (int r0 = std::min(rf, h - 2); r0 >= std::max(rf - 1, 0); --r0) {
      const double fx = c - c0, fy = r - r0;
      if (fx < 0 || fx > 1 || fy < 0 || fy > 1) continue;
      const std::size_t tl = static_cast<std::size_t>(r0) * w + c0, tr = tl + 1, bl = tl + w, br = bl + 1;
      // Triangle (TL, BL, BR) holds fy >= fx, (TL, BR, TR) fx >= fy.
      if (fy >= fx && valid[tl] && valid[bl] && valid[br]) return z[tl] + fx * (z[br] - z[bl]) + fy * (z[bl] - z[tl]);
      if (fx >= fy && valid[tl] && valid[br] && valid[tr]) return z[tl] + fx * (z[tr] - z[tl]) + fy * (z[br] - z[tr]);
    }
  }
  return NAN;
}

// A DEM made ready for lines of sight: its frame, its heights in metres (for the surface under an
// observer) and the quadtree over the triangles that block (those with data, and within `reach`
// metres of `near` seen from above when reach > 0).
class Sightlines {
 public:
  // (Not copied: heights_ views metres_ or windowHeights_.)
  Sightlines(const Sightlines&) = delete;
  Sightlines& operator=(const Sightlines&) = delete;
  // An observer (or a light) placed: its frame point, the surface under it and where it is.
  struct Placed {
    Eigen::Vector3d point;
    double surface, col, row;  // metres over the DEM's reference; pixel position
  };

  // holes: voids are holes, their triangles left out (viewsheds); else they are filled from their
  // rims and block, as for shadows (light cannot pass under the terrain). The frame is placed by
  // place() (the basis and the heights in metres are ready for observerAt before it).
  // takeHeights: the DEM's own heights (dem.heights), moved here instead of copied.
  Sightlines(const DemTerrain& dem, const FrameOptions& frameOptions, const IndexOptions& indexOptions,
             const Progress& report, bool holes = true, std::vector<double>* takeHeights = nullptr)
      : dem_(dem), holes_(holes), options_(frameOptions), indexOptions_(indexOptions) {
    if (dem.width < 2 || dem.height < 2) {
      throw Error(dem.path + ": a viewshed needs a raster of at least 2 x 2 pixels, this one has " +
                  std::to_string(dem.width) + " x " + std::to_string(dem.height));
    }
    const std::size_t n = static_cast<std::size_t>(dem.width) * dem.height;
    if (dem.heights.size() != n && dem.mesh.vertices.size() != n) {
      throw Error(dem.path + ": the DEM holds no heights for its " + std::to_string(dem.width) + " x " +
                  std::to_string(dem.height) + " pixels (an earlier viewshed took them over); load it again");
    }
    if (report) report(0.0, "placing the terrain");
    options_.fillVoids = !holes;
    basis_ = frameBasis(dem, options_);
    // A flat frame of a viewshed places its pixels' points on demand: the sweep reads the
    // heights, and its exact tests the few points under their lines of sight (a whole raster's
    // points would be 24 bytes a pixel). index() places every vertex (the border's too).
    if (holes && !basis_.shared.body.ellipsoid) flat_.emplace(basis_);
    if (takeHeights && takeHeights == &dem.heights && dem.heights.size() == n) {
      metres_ = std::move(*takeHeights);  // (dem_ is not asked for its heights again)
      takeHeights->clear();
    } else {
      metres_.resize(n);
      for (std::size_t i = 0; i < n; ++i) metres_[i] = dem.heightOf(i);
    }
    heightsInMetres(basis_, PixelWindow{0, 0, dem.width, dem.height}, metres_, valid_);
  }

  // The frame over the whole raster, or (holes only) over the pixels within `reach` metres of
  // the observer seen from above, with a margin: its window grows until every pixel on its sides
  // inside the raster lies beyond reach.
  void place(const Placed* observer = nullptr, double reach = 0) {
    const int w = dem_.width, h = dem_.height;
    const RasterGrid::Closure& closure = basis_.closure;
    if (observer && reach > 0 && holes_ && !closure.wrapsColumns && !closure.northCap && !closure.southCap) {
      // Metres a pixel near the observer, from the frame's own placement.
      const double col = observer->col, row = observer->row;
      const double cs[4] = {col - 0.5, col + 0.5, col, col}, rs[4] = {row, row, row - 0.5, row + 0.5};
      const double zs[4] = {0, 0, 0, 0};
      const auto p = framePoints(basis_, cs, rs, zs);
      const double dx = (p[1] - p[0]).norm(), dy = (p[3] - p[2]).norm();
      diagonal_ = std::hypot(dx, dy);
      reach += 3 * diagonal_;  // every pixel a triangle that meets the disc can have as a corner, and more
      for (double grow = 1.25; grow < 100; grow *= 2) {
        const double hc = std::ceil(reach / dx * grow) + 2, hr = std::ceil(reach / dy * grow) + 2;
        const int c0 = static_cast<int>(std::max(0.0, std::floor(col - hc)));
        const int c1 = static_cast<int>(std::min<double>(w, std::ceil(col + hc)));
        const int r0 = static_cast<int>(std::max(0.0, std::floor(row - hr)));
        const int r1 = static_cast<int>(std::min<double>(h, std::ceil(row + hr)));
        if (c1 - c0 < 2 || r1 - r0 < 2 || (c0 == 0 && r0 == 0 && c1 == w && r1 == h)) break;
        placeWindow({c0, r0, c1 - c0, r1 - r0});
        if (sidesBeyond(observer->point, reach)) return;
      }
    }
    placeWindow({0, 0, w, h});
  }

  // The threads placing a frame's points may take (place(); 0: one per core).
  void placingThreads(unsigned threads) { threads_ = threads; }

  // A pixel's diagonal near the observer in metres (set by place with a reach; else 0).
  double diagonal() const { return diagonal_; }
  const LocalFrame& frame() const { return frame_; }
  // Refraction by the standard coefficient model: a line of sight bends toward the body with a
  // curvature k / R, which is the straight line over a body of radius R / (1 - k); so every point
  // of the terrain is raised by k d^2 / (2 R) along its up, d its distance from the observer seen
  // from above, R the body's mean radius. (A model, as every viewshed tool's: exact in the
  // curvature, approximate in the bending.) Call before index().
  void refract(const Eigen::Vector3d& observer, double k) {
    if (k == 0) return;
    const LocalFrame::Body& body = frame_.body;
    const double radius = (2 * body.a + body.b) / 3;
    const Eigen::Vector3d up = frame_.upAt(observer);
    for (Eigen::Vector3d& v : frame_.mesh.vertices) {
      const double d = horizontal(v - observer, up);
      v += frame_.upAt(v) * (k * d * d / (2 * radius));
    }
  }

  // Per raster pixel: the DEM has a height there.
  const std::vector<std::uint8_t>& valid() const { return valid_; }

  // The observer `height` metres above the surface at world (x, y): its frame point and the
  // surface's height there (metres over the DEM's reference). `what` names it in errors.
  Placed observerAt(double x, double y, double height, const std::string& what) const {
    if (!std::isfinite(x) || !std::isfinite(y)) {
      throw Error(what + " must be finite, got " + number(x) + ", " + number(y));
    }
    const double xr = dem_.turnedOnto(x);
    if (!dem_.onRaster(xr, y)) throw Error(what + " at " + number(x) + ", " + number(y) + " is not on " + dem_.path);
    const auto [col, row] = dem_.pixelOf(xr, y);
    const double surface = surfaceAt(metres_, valid_, dem_.width, dem_.height, col, row);
    if (std::isnan(surface)) {
      throw Error(what + " at " + number(x) + ", " + number(y) + " is over a void of " + dem_.path +
                  " (no data there)");
    }
    return {pointAt(col, row, surface + height), surface, col, row};
  }

  // The frame point at pixel position (col, row) and `height` metres over the DEM's reference,
  // anywhere (on the raster or beyond it).
  Eigen::Vector3d pointAt(double col, double row, double height) const {
    const double c[1] = {col}, r[1] = {row}, z[1] = {height};
    return framePoints(basis_, c, r, z)[0];
  }
  const DemTerrain& dem() const { return dem_; }

  // Frame vertex i: the placed one, or in a flat frame without its vertices a pixel's (i below
  // pixelCount(): the sweep's exact tests read the inner triangles alone), the same bits placed now.
  Eigen::Vector3d vertex(std::size_t i) const {
    if (!frame_.mesh.vertices.empty()) return frame_.mesh.vertices[i];
    const int w = frame_.width;
    const PixelWindow& win = frame_.window;
    return flat_->at(static_cast<double>(win.col + static_cast<int>(i % w)) + 0.5,
                     static_cast<double>(win.row + static_cast<int>(i / w)) + 0.5, heights_[i]);
  }
  // Its height (a flat frame places a pixel's vertex at the pixel's height).
  double vertexZ(std::size_t i) const {
    return frame_.mesh.vertices.empty() ? heights_[i] : frame_.mesh.vertices[i].z();
  }

  // The quadtree over the triangles with data; with reach > 0, only those whose corners all lie
  // within reach of `near` seen from above (along `up`).
  void index(const Eigen::Vector3d& near, const Eigen::Vector3d& up, double reach) {
    if (frame_.mesh.vertices.empty()) placeVertices(frame_, basis_, heights_, threads_);
    const std::size_t n = frame_.pixelCount();
    const auto& v = frame_.mesh.vertices;
    const auto& extra = frame_.grid.extraVertices();
    Mesh terrain;
    terrain.vertices = v;
    frame_.grid.appendTriangles(terrain, [&](std::uint32_t k) {
      if (reach > 0 && !(horizontal(v[k] - near, up) <= reach)) return false;
      if (!holes_) return true;  // (filled)
      if (k < n) return frame_.valid[k] != 0;
      const RasterGrid::ExtraVertex& e = extra[k - n];
      return e.pole != 0 || frame_.valid[e.pixel] != 0;
    });
    if (terrain.polygonCount() == 0) {
      throw Error(dem_.path + ": no terrain to see (no square of pixels with data" +
                  (reach > 0 ? std::string(" within the maximum distance)") : std::string(")")));
    }
    // Each inner triangle's number in the raster rule (RasterGrid::innerTriangle) and back, for
    // guessing from a neighbour's blocker (guess()).
    squareOf_.assign(terrain.polygonCount(), CartesianIndex::kNoPolygon);
    triangleAt_.assign(frame_.grid.innerTriangleCount(), CartesianIndex::kNoPolygon);
    for (std::size_t p = 0; p < terrain.polygonCount(); ++p) {
      const auto c = terrain.polygon(p);
      if (const auto slot = frame_.grid.innerTriangleWith(c[0], c[1], c[2])) {  // (not the border, a seam, a cap)
        squareOf_[p] = static_cast<std::uint32_t>(*slot);
        triangleAt_[*slot] = static_cast<std::uint32_t>(p);
      }
    }
    index_ = std::make_unique<CartesianIndex>(terrain, CartesianMapping(), indexOptions_);
  }

  // The polygon of a triangle in the 3 x 3 squares around `blocker`'s (a triangle that blocked a
  // neighbouring line of sight) that the open segment from a to b meets, by the index's own rule
  // (segmentMeetsTriangle; endVertex and skip as segmentMeets), or kNoPolygon. Lines of sight to
  // neighbouring pixels pass within a pixel of each other before their targets, so a ridge that
  // hides one mostly hides the other there: one guess, a few dozen side tests, in place of a walk.
  // A triangle met answers as the walk would (it would find one); none found says nothing.
  std::uint32_t guess(std::uint32_t blocker, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                      std::uint32_t endVertex, std::span<const std::uint32_t> skip) const {
    if (blocker >= squareOf_.size() || squareOf_[blocker] == CartesianIndex::kNoPolygon)
      return CartesianIndex::kNoPolygon;
    const int w = frame_.width, h = frame_.height;
    const std::uint32_t square = squareOf_[blocker] / 2;
    const int col = static_cast<int>(square % (w - 1)), row = static_cast<int>(square / (w - 1));
    const Eigen::Vector3d d = b - a;
    static constexpr int kOrder[3] = {0, -1, 1};
    for (int dr : kOrder) {
      for (int dc : kOrder) {
        const int c = col + dc, r = row + dr;
        if (c < 0 || r < 0 || c > w - 2 || r > h - 2) continue;
        for (std::uint32_t half = 0; half < 2; ++half) {
          const std::uint64_t slot = RasterGrid::innerTriangle(w, r, c, half);
          const std::uint32_t p = triangleAt_[slot];
          if (p == CartesianIndex::kNoPolygon) continue;
          const std::array<std::uint32_t, 3> k = frame_.grid.triangle(slot);
          if (!skip.empty() && std::binary_search(skip.begin(), skip.end(), p)) continue;
          if (meetsTriangle(k, a, d, endVertex)) return p;
        }
      }
    }
    return CartesianIndex::kNoPolygon;
  }

  // Whether the open segment from a to a + d meets the triangle with corners k, by the index's
  // own rule (segmentMeetsTriangle); a triangle with endVertex as a corner meets it only at its
  // end and is left out, as segmentMeets leaves it.
  bool meetsTriangle(const std::array<std::uint32_t, 3>& k, const Eigen::Vector3d& a, const Eigen::Vector3d& d,
                     std::uint32_t endVertex) const {
    if (k[0] == endVertex || k[1] == endVertex || k[2] == endVertex) return false;
    double q[3][3];  // the corners' offsets from a (line_crossing.hpp)
    for (int j = 0; j < 3; ++j) {
      const Eigen::Vector3d corner = vertex(k[j]);
      for (int i = 0; i < 3; ++i) q[j][i] = corner[i] - a[i];
    }
    return detail::segmentMeetsTriangle(q, d);
  }

  // Whether the open segment from a to b meets the terrain (segmentMeets), trying `blocker`'s
  // neighbourhood first (guess); blocker becomes the triangle met, when one is.
  bool meets(std::uint32_t& blocker, const Eigen::Vector3d& a, const Eigen::Vector3d& b, std::uint32_t endVertex,
             std::span<const std::uint32_t> skip = {}) const {
    std::uint32_t met = guess(blocker, a, b, endVertex, skip);
    if (met == CartesianIndex::kNoPolygon) met = index_->segmentMeetsWhich(a, b, endVertex, skip);
    if (met == CartesianIndex::kNoPolygon) return false;
    blocker = met;
    return true;
  }

  const CartesianIndex& index() const { return *index_; }

  static double horizontal(const Eigen::Vector3d& d, const Eigen::Vector3d& up) { return (d - d.dot(up) * up).norm(); }

  // Sight of every pixel from `observer` (a frame point `height` metres above the surface):
  // visit(i, sight) for each pixel with data, on `threads` threads (visit must be safe for
  // different pixels at once). Returns false when progress cancelled.
  template <class Visit>
  bool look(const Eigen::Vector3d& observer, double height, double targetHeight, double maxDistance, unsigned threads,
            const Progress& progress, double from, double span, const Visit& visit) const {
    const CartesianIndex& index = *index_;
    // An observer on the surface stands on its own triangles: they meet every segment at its start.
    std::vector<std::uint32_t> standsOn;
    if (height == 0) {
      for (const Hit& hit : index.allWorld(observer)) {
        if (std::fabs(hit.height - observer.z()) <= 1e-9 * (1 + std::fabs(observer.z()))) {
          standsOn.push_back(hit.polygon);
        }
      }
      std::sort(standsOn.begin(), standsOn.end());
    }
    const Eigen::Vector3d up = frame_.upAt(observer);
    const auto& v = frame_.mesh.vertices;
    const int w = frame_.width;
    const PixelWindow& win = frame_.window;
    return inRows(threads, progress, from, span, "testing lines of sight", [&](std::size_t r) {
      // Frame pixel i is the raster's pixel `at` (the frame may be a window of it).
      const std::size_t rowStart = (win.row + r) * static_cast<std::size_t>(dem_.width) + win.col - r * w;
      std::uint32_t blocker = CartesianIndex::kNoPolygon;  // the last pixel's, along the row
      for (std::size_t i = r * w; i < (r + 1) * w; ++i) {
        if (!frame_.valid[i]) continue;
        const std::size_t at = rowStart + i;
        if (maxDistance > 0 && horizontal(v[i] - observer, up) > maxDistance) {
          visit(at, Sight::OutOfRange);
          continue;
        }
        // A target on the surface is the vertex itself, whose own triangles meet its segment only there.
        const bool onSurface = targetHeight == 0;
        const Eigen::Vector3d target = onSurface ? v[i] : v[i] + targetHeight * frame_.upAt(v[i]);
        const bool blocked = meets(blocker, observer, target,
                                   onSurface ? static_cast<std::uint32_t>(i) : CartesianIndex::kNoVertex, standsOn);
        visit(at, blocked ? Sight::Hidden : Sight::Visible);
      }
    });
  }

  // Whether lines of sight from `eye` (placed, `height` metres over the surface) can be decided by
  // the sweep (viewshed_sweep.hpp): a flat frame, an eye above the surface and strictly inside the
  // outermost centres' lines (then no line of sight reaches the outer half pixel).
  bool sweepable(const Placed& eye, double height) const {
    if (frame_.body.ellipsoid || !(height > 0) || !frame_.gridMesh) return false;
    const double x = eye.col - 0.5 - frame_.window.col, y = eye.row - 0.5 - frame_.window.row;
    return x > 0 && y > 0 && x < frame_.width - 1 && y < frame_.height - 1;
  }

  // Sight of every pixel from a sweepable eye: the sweep's verdicts, and for the pixels it leaves
  // undecided the exact test of every triangle under the line of sight (walkMeets); visit as
  // look's. Returns false when progress cancelled.
  template <class Visit>
  bool sweepLook(const Placed& eye, double height, double targetHeight, double maxDistance, unsigned threads,
                 const Progress& progress, double from, double span, const Visit& visit, qota::sweep::Counts& counts) {
    const LocalFrame& f = frame_;
    const std::size_t n = f.pixelCount();
    const int w = f.width, h = f.height;
    // The grid's heights: in a flat frame a vertex's height is the height it was placed at.
    const std::span<const double> z = heights_;
    // The largest height difference between neighbouring pixels (metres), slices of rows on the
    // threads.
    double steepest = 0;
    std::mutex steepestLock;
    batch::inSlices(static_cast<std::size_t>(h), threads, 64, [&](std::size_t lo, std::size_t hi) {
      double most = 0;
      for (std::size_t r = lo; r < hi; ++r) {
        const double* row = z.data() + r * w;
        for (int c = 0; c + 1 < w; ++c) most = std::max(most, std::fabs(row[c + 1] - row[c]));
        if (r + 1 == static_cast<std::size_t>(h)) continue;
        for (int c = 0; c < w; ++c) most = std::max(most, std::fabs(row[c + w] - row[c]));
      }
      const std::lock_guard<std::mutex> hold(steepestLock);
      steepest = std::max(steepest, most);
    });
    const qota::sweep::Eye at{eye.col - 0.5 - f.window.col, eye.row - 0.5 - f.window.row, eye.point.z(), height};
    // The frame's ground coordinates are rounded (to a few units in the last place of the
    // world's coordinates, here bounded with room); a point moved that far in pixels changes a
    // height by at most the steepest slope times it.
    const auto& gt = dem_.geotransform;
    const double units =
        std::fabs(gt[0]) + std::fabs(gt[3]) +
        (dem_.width + dem_.height) * (std::fabs(gt[1]) + std::fabs(gt[2]) + std::fabs(gt[4]) + std::fabs(gt[5]));
    const double metresPerUnit = dem_.crsWkt.empty() ? 1.0 : f.pixelSizeX / std::max(std::hypot(gt[1], gt[4]), 1e-300);
    const double pixels = (64 * std::numeric_limits<double>::epsilon() * units * metresPerUnit + 1e-12) /
                          std::max(std::min(f.pixelSizeX, f.pixelSizeY), 1e-300);
    const double slack = pixels * (4 * steepest + 1);
    std::vector<qota::sweep::Verdict> verdict(n, qota::sweep::Verdict::Undecided);
    const auto keepGoing = [&](double fraction) {
      return !progress || progress(from + 0.8 * span * fraction, "sweeping lines of sight");
    };
    if (!qota::sweep::decide(qota::sweep::Grid{w, h, z, f.valid}, at, targetHeight, slack, threads, verdict, counts,
                             keepGoing)) {
      return false;
    }
    // The undecided, tested one by one.
    const Eigen::Vector3d up = f.upAt(eye.point);
    const PixelWindow& win = f.window;
    std::vector<std::uint32_t> undecided;
    counts = {};  // (of the pixels in range)
    for (int r = 0; r < h; ++r) {
      const std::size_t rowAt = static_cast<std::size_t>(r) * w;
      const std::size_t rasterAt = static_cast<std::size_t>(win.row + r) * dem_.width + win.col;
      for (int c = 0; c < w; ++c) {
        const std::size_t i = rowAt + c;
        if (!f.valid[i]) continue;
        if (maxDistance > 0 && horizontal(vertex(i) - eye.point, up) > maxDistance) {
          visit(rasterAt + c, Sight::OutOfRange);
        } else if (verdict[i] == qota::sweep::Verdict::Undecided) {
          undecided.push_back(static_cast<std::uint32_t>(i));
        } else {
          visit(rasterAt + c, verdict[i] == qota::sweep::Verdict::Visible ? Sight::Visible : Sight::Hidden);
          ++counts.decided;
        }
      }
    }
    counts.undecided = undecided.size();
    if (!undecided.empty() && walkLow_.empty()) walkBlocks(threads);
    std::atomic<std::size_t> next{0};
    shadow::inThreads(threads, [&](unsigned) {
      for (std::size_t k; (k = next++) < undecided.size();) {
        const std::uint32_t i = undecided[k];
        const std::size_t col = i % static_cast<std::size_t>(w), row = i / static_cast<std::size_t>(w);
        const bool onSurface = targetHeight == 0;
        const Eigen::Vector3d p = vertex(i);
        const Eigen::Vector3d target = onSurface ? p : p + targetHeight * f.upAt(p);
        const bool blocked = walkMeets(eye.point, target, at.x, at.y, static_cast<double>(col),
                                       static_cast<double>(row), onSurface ? i : CartesianIndex::kNoVertex);
        const std::size_t atRaster = (win.row + row) * static_cast<std::size_t>(dem_.width) + win.col + col;
        visit(atRaster, blocked ? Sight::Hidden : Sight::Visible);
      }
    });
    if (progress && !progress(from + span, "testing lines of sight")) return false;
    return true;
  }

  // Whether the open segment from frame point a to b meets a triangle with data, testing every
  // inner triangle of the squares its ground track (ax, ay) to (bx, by) (pixel coordinates of the
  // frame) touches, each by the index's own rule (segmentMeetsTriangle; endVertex's triangles left
  // out as segmentMeets leaves them). The same answer as the index's walk, which tests a subset of
  // these by the same rule, for segments inside the outermost centres' lines.
  // On an ellipsoid with the observer's model ready (model()), the track is the segment's in the
  // model, the squares are padded by the model's pad, heights are the model's and the border's
  // triangles join where the padded track reaches them: the same answer for any segment from the
  // observer. metSquare: the square (row (width - 1) + col) of the triangle met, when one is.
  bool walkMeets(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double ax, double ay, double bx, double by,
                 std::uint32_t endVertex, std::int64_t* metSquare = nullptr) const {
    const int w = frame_.width, h = frame_.height;
    const Eigen::Vector3d d = b - a;
    // Pixels: a flat frame's, far beyond the rounding of the track (a superset); a model's, its
    // vertices' largest distance from their pixels' positions (model()).
    const double pad = model_ ? model_->pad : 1e-7;
    const double za = heightOf(a), zb = heightOf(b), dz = zb - za;
    const int c0 = std::max(0, static_cast<int>(std::floor(std::min(ax, bx) - pad)));
    const int c1 = std::min(w - 2, static_cast<int>(std::floor(std::max(ax, bx) + pad)));
    // A square whose corners all lie above the segment's heights over its column, or all below,
    // by more than any rounding here or in the frame's coordinates, holds no triangle it meets.
    const double margin = 1e-6 + 1e-9 * (std::fabs(za) + std::fabs(zb));
    // The track over squares' columns [from, to] (clamped to the segment, padded): its rows and
    // the segment's heights there.
    const auto span = [&](int from, int to, double& y0, double& y1, double& lineLow, double& lineHigh) {
      double z0 = za, z1 = zb;
      y0 = ay, y1 = by;
      if (bx != ax) {
        const double u0 = std::clamp((from - pad - ax) / (bx - ax), 0.0, 1.0);
        const double u1 = std::clamp((to + 1 + pad - ax) / (bx - ax), 0.0, 1.0);
        y0 = ay + u0 * (by - ay), y1 = ay + u1 * (by - ay);
        z0 = za + u0 * dz, z1 = za + u1 * dz;
      }
      lineLow = std::min(z0, z1) - margin, lineHigh = std::max(z0, z1) + margin;
    };
    const auto rows = [&](double y0, double y1, int& r0, int& r1) {
      r0 = std::max(0, static_cast<int>(std::floor(std::min(y0, y1) - pad)));
      r1 = std::min(h - 2, static_cast<int>(std::floor(std::max(y0, y1) + pad)));
    };
    // The segment's heights over the part of its track within squares' columns [from, to] and
    // rows [top, bottom] (padded; false when the track does not come that near).
    const auto cellSpan = [&](int from, int to, int top, int bottom, double& lineLow, double& lineHigh) {
      double u0 = 0, u1 = 1;
      const auto within = [&](double start, double step, double lo, double hi) {
        if (step == 0) return;  // (the whole segment: the blocks were chosen along the track)
        const double ua = (lo - pad - start) / step, ub = (hi + pad - start) / step;
        u0 = std::max(u0, std::min(ua, ub)), u1 = std::min(u1, std::max(ua, ub));
      };
      within(ax, bx - ax, from, to + 1);
      within(ay, by - ay, top, bottom + 1);
      if (!(u0 <= u1)) return false;
      const double z0 = za + u0 * dz, z1 = za + u1 * dz;
      lineLow = std::min(z0, z1) - margin, lineHigh = std::max(z0, z1) + margin;
      return true;
    };
    if (model_) {
      if (ringMeets(a, d, ax, ay, bx, by, pad, endVertex)) return true;
      return shiftedWalkMeets(a, d, ax, ay, bx, by, za, zb, margin, endVertex, metSquare);
    }
    std::vector<std::uint8_t> cellClear;  // of the block column's blocks, from its first row's
    for (int block = c0 / kWalkBlock; block <= c1 / kWalkBlock; ++block) {
      const int from = std::max(c0, block * kWalkBlock), to = std::min(c1, block * kWalkBlock + kWalkBlock - 1);
      // The blocks of squares the track touches in this block column first, each with the
      // segment's heights over that block alone: one wholly above or below the segment there (a
      // line of sight clear of the terrain for a while; a steep line's track crosses many blocks
      // of rows in one block column) is passed at once.
      double y0, y1, lineLow, lineHigh;
      int r0, r1;
      span(from, to, y0, y1, lineLow, lineHigh);
      rows(y0, y1, r0, r1);
      const int br0 = r0 / kWalkBlock, br1 = r1 / kWalkBlock;
      cellClear.assign(static_cast<std::size_t>(br1 - br0) + 1, 0);
      bool clear = true;
      for (int br = br0; br <= br1; ++br) {
        const std::size_t at = static_cast<std::size_t>(br) * walkBlocksAcross_ + block;
        double low, high;
        cellClear[br - br0] = !cellSpan(from, to, br * kWalkBlock, br * kWalkBlock + kWalkBlock - 1, low, high) ||
                              walkLow_[at] > high || walkHigh_[at] < low;
        clear = clear && cellClear[br - br0];
      }
      if (clear) continue;
      for (int c = from; c <= to; ++c) {
        span(c, c, y0, y1, lineLow, lineHigh);
        rows(y0, y1, r0, r1);
        for (int r = r0; r <= r1; ++r) {
          const int br = r / kWalkBlock;
          if (br >= br0 && br <= br1 && cellClear[br - br0]) {
            r = br * kWalkBlock + kWalkBlock - 1;  // (the block's last row; the loop steps past it)
            continue;
          }
          if (squareMet(c, r, lineLow, lineHigh, a, d, endVertex, metSquare)) return true;
        }
      }
    }
    return false;
  }

  // walkMeets in a model: block by block, each block's corners' model positions shifted back by
  // the block's own offset (Model::Block), so that the track is sought within the block's small
  // spread instead of the whole raster's pad. The blocks a track can reach are those within the
  // pad of it; in each, the squares within the spread of the shifted track, their triangles
  // tested exactly in the frame. (The pad grows with the distance from the observer on a
  // geographic raster, the spread within a block stays a small fraction of a pixel.)
  bool shiftedWalkMeets(const Eigen::Vector3d& a, const Eigen::Vector3d& d, double ax, double ay, double bx, double by,
                        double za, double zb, double margin, std::uint32_t endVertex, std::int64_t* metSquare) const {
    const int w = frame_.width, h = frame_.height;
    const Model& m = *model_;
    const double pad = m.pad, dz = zb - za;
    // [u0, u1] narrowed to where start + u step lies in [lo, hi]; false when empty. (By the
    // step's reciprocal, one division a track instead of two a test: the parameters move by an
    // ulp or so, far inside the spreads' and the pad's slack of 1e-6 pixel.)
    struct Axis {
      double step, inverse;
    };
    const Axis across{bx - ax, 1 / (bx - ax)}, down{by - ay, 1 / (by - ay)};
    const auto clip = [](double start, const Axis& axis, double lo, double hi, double& u0, double& u1) {
      if (axis.step == 0) return start >= lo && start <= hi && u0 <= u1;
      const double ua = (lo - start) * axis.inverse, ub = (hi - start) * axis.inverse;
      u0 = std::max(u0, std::min(ua, ub)), u1 = std::min(u1, std::max(ua, ub));
      return u0 <= u1;
    };
    const auto heights = [&](double u0, double u1, double& low, double& high) {
      const double z0 = za + u0 * dz, z1 = za + u1 * dz;
      low = std::min(z0, z1) - margin, high = std::max(z0, z1) + margin;
    };
    const int lastColumn = w - 2, lastRow = h - 2;
    const int bc0 = std::max(0, static_cast<int>(std::floor(std::min(ax, bx) - pad))) / kWalkBlock;
    const int bc1 = std::min(lastColumn, static_cast<int>(std::floor(std::max(ax, bx) + pad))) / kWalkBlock;
    for (int bc = bc0; bc <= bc1; ++bc) {
      const int c0 = bc * kWalkBlock, c1 = std::min(lastColumn, c0 + kWalkBlock - 1);
      // The block rows the track can reach over these columns (within the pad).
      double v0 = 0, v1 = 1;
      if (!clip(ax, across, c0 - pad, c1 + 1 + pad, v0, v1)) continue;
      const double ya = ay + v0 * (by - ay), yb = ay + v1 * (by - ay);
      const int br0 = std::max(0, static_cast<int>(std::floor(std::min(ya, yb) - pad))) / kWalkBlock;
      const int br1 = std::min(lastRow, static_cast<int>(std::floor(std::max(ya, yb) + pad))) / kWalkBlock;
      for (int br = br0; br <= br1; ++br) {
        const std::size_t at = static_cast<std::size_t>(br) * walkBlocksAcross_ + bc;
        const Model::Block& s = m.blocks[at];
        const int r0 = br * kWalkBlock, r1 = std::min(lastRow, r0 + kWalkBlock - 1);
        // The shifted track within the block's squares, widened by its spread.
        const double sx = ax - s.dx, sy = ay - s.dy;
        double u0 = 0, u1 = 1;
        if (!clip(sx, across, c0 - s.rx, c1 + 1 + s.rx, u0, u1) || !clip(sy, down, r0 - s.ry, r1 + 1 + s.ry, u0, u1)) {
          continue;
        }
        double low, high;
        heights(u0, u1, low, high);
        if (walkLow_[at] > high || walkHigh_[at] < low) continue;
        for (int c = c0; c <= c1; ++c) {
          double t0 = u0, t1 = u1;
          if (!clip(sx, across, c - s.rx, c + 1 + s.rx, t0, t1)) continue;
          const double y0 = sy + t0 * (by - ay), y1 = sy + t1 * (by - ay);
          const int ra = std::max(r0, static_cast<int>(std::floor(std::min(y0, y1) - s.ry)));
          const int rb = std::min(r1, static_cast<int>(std::floor(std::max(y0, y1) + s.ry)));
          heights(t0, t1, low, high);
          for (int r = ra; r <= rb; ++r) {
            if (squareMet(c, r, low, high, a, d, endVertex, metSquare)) return true;
          }
        }
      }
    }
    return false;
  }

  // Whether the segment, its heights over square (c, r) within [low, high], meets a triangle of
  // the square: none when the square's corners all lie above or all below those heights (its
  // triangles within its corners' heights), else squareMeets; metSquare (when given) the square.
  bool squareMet(int c, int r, double low, double high, const Eigen::Vector3d& a, const Eigen::Vector3d& d,
                 std::uint32_t endVertex, std::int64_t* metSquare) const {
    const int w = frame_.width;
    const std::size_t tl = static_cast<std::size_t>(r) * w + c;
    const double zA = zOf(tl), zB = zOf(tl + 1), zC = zOf(tl + w), zD = zOf(tl + w + 1);
    if (std::min({zA, zB, zC, zD}) > high || std::max({zA, zB, zC, zD}) < low) return false;
    if (!squareMeets(c, r, a, d, endVertex)) return false;
    if (metSquare) *metSquare = static_cast<std::int64_t>(r) * (w - 1) + c;
    return true;
  }

  // Whether the open segment from a to a + d meets an inner triangle of square (c, r) that blocks
  // (with holes, one with data: blocks()).
  bool squareMeets(int c, int r, const Eigen::Vector3d& a, const Eigen::Vector3d& d, std::uint32_t endVertex) const {
    const int w = frame_.width;
    for (std::uint32_t half = 0; half < 2; ++half) {
      const std::array<std::uint32_t, 3> k = RasterGrid::innerCorners(
          static_cast<std::uint32_t>(w), static_cast<std::uint32_t>(r), static_cast<std::uint32_t>(c), half);
      if (!blocks(k)) continue;
      if (meetsTriangle(k, a, d, endVertex)) return true;
    }
    return false;
  }

  // Whether a triangle of the grid blocks lines of sight: with holes (viewsheds) one whose corners
  // all have data, as index() keeps them; filled (lights), every one.
  bool blocks(const std::array<std::uint32_t, 3>& k) const {
    if (!holes_) return true;
    const std::size_t n = frame_.pixelCount();
    const auto& extra = frame_.grid.extraVertices();
    for (const std::uint32_t i : k) {
      if (i < n ? !frame_.valid[i] : extra[i - n].pole == 0 && !frame_.valid[extra[i - n].pixel]) return false;
    }
    return true;
  }

  // A height walkMeets compares: a frame point's, in the model's terms when there is one.
  double heightOf(const Eigen::Vector3d& p) const { return model_ ? model_->up.dot(p - model_->origin) : p.z(); }
  // Vertex i's height in the same terms.
  double zOf(std::size_t i) const { return model_ ? model_->z[i] : vertexZ(i); }

  // ---- Lines of sight on an ellipsoid without a quadtree ----
  //
  // Why the walk stays exact there. The model is a linear image of the frame, centred on the
  // observer: (x, y) its tangent plane's coordinates mapped into pixel units by the inverse of the
  // raster's Jacobian at the observer, z the height along the observer's up. A linear map keeps
  // which segments meet which triangles, and keeps each triangle's points within its corners'
  // heights. Every vertex's model (x, y) lies within `pad` pixels (each coordinate) of its pixel
  // position, measured vertex by vertex; so a triangle whose model projection meets the segment's
  // lies in a square (or a border cell) within pad of the segment's track, which walkMeets pads
  // by as much. The triangles found are then tested exactly in the frame (meetsTriangle).
  struct Model {
    Eigen::Vector3d origin, up;
    Eigen::Matrix<double, 2, 3> plane;  // frame offset -> pixels
    double pad = 0;
    std::vector<double> z;  // each vertex's height along up, from the origin
    // Per block of kWalkBlock x kWalkBlock squares (walkBlocks' blocks): the middle of its
    // corners' offsets (model position less pixel position), and how far any corner's lies from
    // it, by axis.
    struct Block {
      double dx = 0, dy = 0, rx = 0, ry = 0;
    };
    std::vector<Block> blocks;
  };
  // Pads beyond this reach too many blocks a track to pay (a raster spanning tens of degrees):
  // the quadtree answers those.
  static constexpr double kMostPad = 32.0;

  // Whether walkLook can take this observer: on an ellipsoid's frame of the raster's grid (no
  // seam or pole), above the surface, strictly inside the outermost centres' lines.
  bool walkable(const Placed& eye, double height) const {
    return frame_.body.ellipsoid && height > 0 && walkableFrom(eye);
  }
  // The same for any point (a light at an absolute height; a flat frame with its vertices placed
  // too, whose segments stay inside the outermost centres' lines).
  bool walkableFrom(const Placed& eye) const {
    const LocalFrame& f = frame_;
    if (!f.gridMesh || f.mesh.vertices.empty()) return false;
    const RasterGrid::Closure& closure = f.grid.closure();
    if (closure.wrapsColumns || closure.northCap || closure.southCap) return false;
    const double x = eye.col - 0.5 - f.window.col, y = eye.row - 0.5 - f.window.row;
    return x > 0 && y > 0 && x < f.width - 1 && y < f.height - 1;
  }

  // The model of `eye` (above), its vertices' heights and pad measured on `threads` threads;
  // false (and no model) when the pad is beyond kMostPad or the raster's Jacobian there is flat.
  bool model(const Placed& eye, unsigned threads) {
    model_.reset();
    walkLow_.clear(), walkHigh_.clear();
    const LocalFrame& f = frame_;
    auto m = std::make_unique<Model>();
    m->origin = eye.point;
    // Up: the normal the observer was placed along (from the surface under it), so that it stands
    // over its own pixel position in the model however high it is.
    // (A light at an absolute height has no surface under it here: any height gives the normal.)
    const double surface = std::isfinite(eye.surface) ? eye.surface : 0.0;
    const Eigen::Vector3d foot = pointAt(eye.col, eye.row, surface);
    m->up = (pointAt(eye.col, eye.row, surface + 1000) - foot).normalized();
    const Eigen::Vector3d e1 = m->up.unitOrthogonal(), e2 = m->up.cross(e1);
    const auto tangent = [&](const Eigen::Vector3d& v) { return Eigen::Vector2d(e1.dot(v), e2.dot(v)); };
    Eigen::Matrix2d jacobian;
    try {
      jacobian.col(0) = tangent(pointAt(eye.col + 1, eye.row, surface) - pointAt(eye.col - 1, eye.row, surface)) / 2;
      jacobian.col(1) = tangent(pointAt(eye.col, eye.row + 1, surface) - pointAt(eye.col, eye.row - 1, surface)) / 2;
    } catch (const Error&) {
      return false;  // (a point a pixel from the observer beyond the CRS, a pole or the geoid grid)
    }
    if (!(std::fabs(jacobian.determinant()) > 0) || !jacobian.allFinite()) return false;
    Eigen::Matrix<double, 2, 3> tangents;
    tangents.row(0) = e1.transpose(), tangents.row(1) = e2.transpose();
    m->plane = jacobian.inverse() * tangents;
    const auto& v = f.mesh.vertices;
    const int w = f.width;
    const std::size_t n = f.pixelCount();
    const auto& extra = f.grid.extraVertices();
    const double ex = eye.col - 0.5 - f.window.col, ey = eye.row - 0.5 - f.window.row;
    m->z.resize(v.size());
    std::mutex most;
    batch::inSlices(v.size(), threads, 1 << 16, [&](std::size_t lo, std::size_t hi) {
      double pad = 0;
      for (std::size_t i = lo; i < hi; ++i) {
        const Eigen::Vector3d offset = v[i] - m->origin;
        m->z[i] = m->up.dot(offset);
        const Eigen::Vector2d xy = m->plane * offset;
        // The vertex's pixel position, from the observer's (pixel centres at whole numbers).
        const double px = i < n ? static_cast<double>(i % w) : extra[i - n].col - 0.5;
        const double py = i < n ? static_cast<double>(i / w) : extra[i - n].row - 0.5;
        pad = std::max({pad, std::fabs(xy.x() - (px - ex)), std::fabs(xy.y() - (py - ey))});
      }
      const std::lock_guard<std::mutex> hold(most);
      m->pad = std::max(m->pad, pad);
    });
    // (Rounding of the model's coordinates: far below a millionth of a pixel.)
    m->pad += 1e-6;
    if (!(m->pad <= kMostPad)) return false;
    // Each block's offsets: the corners of its squares, pixel rows and columns kWalkBlock b to
    // kWalkBlock b + kWalkBlock (a pixel on a block's side is a corner of the blocks on both sides).
    const int h = f.height;
    const std::size_t across = static_cast<std::size_t>((w - 2) / kWalkBlock) + 1;
    const std::size_t down = static_cast<std::size_t>((h - 2) / kWalkBlock) + 1;
    m->blocks.assign(across * down, {});
    batch::inSlices(down, threads, 4, [&](std::size_t first, std::size_t end) {
      for (std::size_t b = first; b < end; ++b) {
        for (std::size_t c = 0; c < across; ++c) {
          double x0 = INFINITY, x1 = -INFINITY, y0 = INFINITY, y1 = -INFINITY;
          const int rowEnd = std::min(static_cast<int>(b) * kWalkBlock + kWalkBlock, h - 1);
          const int colEnd = std::min(static_cast<int>(c) * kWalkBlock + kWalkBlock, w - 1);
          for (int r = static_cast<int>(b) * kWalkBlock; r <= rowEnd; ++r) {
            for (int k = static_cast<int>(c) * kWalkBlock; k <= colEnd; ++k) {
              const std::size_t i = static_cast<std::size_t>(r) * w + k;
              const Eigen::Vector2d xy = m->plane * (v[i] - m->origin);
              const double ox = xy.x() - (k - ex), oy = xy.y() - (r - ey);
              x0 = std::min(x0, ox), x1 = std::max(x1, ox), y0 = std::min(y0, oy), y1 = std::max(y1, oy);
            }
          }
          // (The spread widened for the rounding of these offsets, as the pad is.)
          m->blocks[b * across + c] = {(x0 + x1) / 2, (y0 + y1) / 2, (x1 - x0) / 2 + 1e-6, (y1 - y0) / 2 + 1e-6};
        }
      }
    });
    model_ = std::move(m);
    ringCells();
    walkBlocks(threads);
    return true;
  }

  // The border's triangles by the ring cells their pixel positions' box overlaps (walk_ring.hpp),
  // for ringMeets.
  void ringCells() {
    const LocalFrame& f = frame_;
    const int w = f.width, h = f.height;
    const std::size_t n = f.pixelCount();
    const auto& extra = f.grid.extraVertices();
    for (int side = 0; side < 4; ++side) ring_[side].assign(side < 2 ? w + 1 : h + 1, {});
    for (std::size_t t = f.grid.innerTriangleCount(); t < f.grid.triangleCount(); ++t) {
      const std::array<std::uint32_t, 3> k = f.grid.triangle(t);
      double c0 = INFINITY, c1 = -INFINITY, r0 = INFINITY, r1 = -INFINITY;
      for (const std::uint32_t i : k) {
        const double x = i < n ? static_cast<double>(i % w) : extra[i - n].col - 0.5;
        const double y = i < n ? static_cast<double>(i / w) : extra[i - n].row - 0.5;
        c0 = std::min(c0, x), c1 = std::max(c1, x), r0 = std::min(r0, y), r1 = std::max(r1, y);
      }
      const int ca = std::max(-1, static_cast<int>(std::floor(c0)));
      const int cb = std::min(w - 1, static_cast<int>(std::floor(c1)));
      const int ra = std::max(-1, static_cast<int>(std::floor(r0)));
      const int rb = std::min(h - 1, static_cast<int>(std::floor(r1)));
      for (int r = ra; r <= rb; ++r) {
        for (int c = ca; c <= cb; ++c) {
          if (c != -1 && c != w - 1 && r != -1 && r != h - 1) continue;  // (an inner square)
          walk::Side side;
          int at;
          walk::ringCellOf(c, r, h, side, at);
          ring_[static_cast<int>(side)][at].push_back(static_cast<std::uint32_t>(t));
        }
      }
    }
  }

  // Whether the open segment from a to a + d meets a border triangle with data in a ring cell its
  // track (ax, ay) to (bx, by), padded, reaches (walk_ring.hpp).
  bool ringMeets(const Eigen::Vector3d& a, const Eigen::Vector3d& d, double ax, double ay, double bx, double by,
                 double pad, std::uint32_t endVertex) const {
    return walk::forRingCells(ax, ay, bx, by, pad, frame_.width, frame_.height, [&](walk::Side side, int k) {
      for (const std::uint32_t t : ring_[static_cast<int>(side)][k]) {
        const std::array<std::uint32_t, 3> c = frame_.grid.triangle(t);
        if (blocks(c) && meetsTriangle(c, a, d, endVertex)) return true;
      }
      return false;
    });
  }

  // Whether the open segment from `eye` (walkable, and modelled on an ellipsoid: model()) to
  // `target`, above frame pixel i, meets the terrain: the square that blocked the segment before
  // (blocker, -1 for none; a ridge that hides one pixel mostly hides the next in the row) and its
  // neighbours first, a few triangles in place of a walk, then walkMeets. blocker becomes the
  // square met, when one is.
  bool walkBlocked(const Placed& eye, const Eigen::Vector3d& target, std::size_t i, std::uint32_t endVertex,
                   std::int64_t& blocker) const {
    const LocalFrame& f = frame_;
    const int w = f.width, h = f.height;
    const Eigen::Vector3d d = target - eye.point;
    if (blocker >= 0) {
      const int bc = static_cast<int>(blocker % (w - 1)), br = static_cast<int>(blocker / (w - 1));
      static constexpr int kOrder[3] = {0, -1, 1};  // (the square itself first)
      for (const int dr : kOrder) {
        for (const int dc : kOrder) {
          const int c = bc + dc, r = br + dr;
          if (c < 0 || r < 0 || c > w - 2 || r > h - 2 || !squareMeets(c, r, eye.point, d, endVertex)) continue;
          blocker = static_cast<std::int64_t>(r) * (w - 1) + c;
          return true;
        }
      }
    }
    const double ex = eye.col - 0.5 - f.window.col, ey = eye.row - 0.5 - f.window.row;
    if (!model_) {  // (a flat frame: a target above pixel i stands over its pixel position)
      return walkMeets(eye.point, target, ex, ey, static_cast<double>(i % w), static_cast<double>(i / w), endVertex,
                       &blocker);
    }
    const Eigen::Vector2d xy = model_->plane * (target - model_->origin);
    return walkMeets(eye.point, target, ex, ey, ex + xy.x(), ey + xy.y(), endVertex, &blocker);
  }

  // Sight of every pixel from an observer walkable and modelled (model()): each line of sight
  // tested by walkBlocked; visit and the rest as look's.
  template <class Visit>
  bool walkLook(const Placed& eye, double targetHeight, double maxDistance, unsigned threads, const Progress& progress,
                double from, double span, const Visit& visit) const {
    const LocalFrame& f = frame_;
    const Eigen::Vector3d up = f.upAt(eye.point);
    const auto& v = f.mesh.vertices;
    const int w = f.width;
    const PixelWindow& win = f.window;
    return inRows(threads, progress, from, span, "testing lines of sight", [&](std::size_t r) {
      const std::size_t rowStart = (win.row + r) * static_cast<std::size_t>(dem_.width) + win.col - r * w;
      std::int64_t blocker = -1;  // along the row
      for (std::size_t i = r * w; i < (r + 1) * w; ++i) {
        if (!f.valid[i]) continue;
        const std::size_t at = rowStart + i;
        if (maxDistance > 0 && horizontal(v[i] - eye.point, up) > maxDistance) {
          visit(at, Sight::OutOfRange);
          continue;
        }
        const bool onSurface = targetHeight == 0;
        const Eigen::Vector3d target = onSurface ? v[i] : v[i] + targetHeight * f.upAt(v[i]);
        const std::uint32_t endVertex = onSurface ? static_cast<std::uint32_t>(i) : CartesianIndex::kNoVertex;
        visit(at, walkBlocked(eye, target, i, endVertex, blocker) ? Sight::Hidden : Sight::Visible);
      }
    });
  }

  // For walkMeets: the lowest and highest height (zOf: the frame's, or the model's when there is
  // one) over each block of kWalkBlock x kWalkBlock squares (the corners of its squares),
  // row-major by blocks; slices of block rows on `threads` threads.
  void walkBlocks(unsigned threads) {
    const int w = frame_.width, h = frame_.height;
    walkBlocksAcross_ = static_cast<std::size_t>((w - 2) / kWalkBlock) + 1;
    const std::size_t across = walkBlocksAcross_, down = static_cast<std::size_t>((h - 2) / kWalkBlock) + 1;
    walkLow_.assign(across * down, INFINITY);
    walkHigh_.assign(across * down, -INFINITY);
    const double* z = model_ ? model_->z.data() : frame_.mesh.vertices.empty() ? heights_.data() : nullptr;
    batch::inSlices(down, threads, 8, [&](std::size_t first, std::size_t end) {
      for (std::size_t b = first; b < end; ++b) {
        // Block b's squares' corners: pixel rows 8 b to 8 b + 8, and for block column c pixel
        // columns 8 c to 8 c + 8 (within the raster). A pixel on a block's side is a corner of
        // the blocks on both sides.
        const int rowEnd = std::min(static_cast<int>(b) * kWalkBlock + kWalkBlock, h - 1);
        for (int r = static_cast<int>(b) * kWalkBlock; r <= rowEnd; ++r) {
          const std::size_t row = static_cast<std::size_t>(r) * w;
          for (std::size_t c = 0; c < across; ++c) {
            const int x0 = static_cast<int>(c) * kWalkBlock, x1 = std::min(x0 + kWalkBlock, w - 1);
            double lo = INFINITY, hi = -INFINITY;
            for (int x = x0; x <= x1; ++x) {
              const double v = z ? z[row + x] : vertexZ(row + x);
              lo = std::min(lo, v), hi = std::max(hi, v);
            }
            const std::size_t at = b * across + c;
            walkLow_[at] = std::min(walkLow_[at], lo), walkHigh_[at] = std::max(walkHigh_[at], hi);
          }
        }
      }
    });
  }

  // row(r) for every row of the frame, rows handed out to `threads` threads in turn (a row's
  // lines of sight share their blocker guess, so a row is one thread's), progress from `from`
  // over `span` after each. Returns false when progress cancelled.
  template <class Row>
  bool inRows(unsigned threads, const Progress& progress, double from, double span, const char* what,
              const Row& row) const {
    const auto h = static_cast<std::size_t>(frame_.height);
    std::atomic<std::size_t> nextRow{0}, rowsDone{0};
    std::atomic<bool> stop{false};
    shadow::inThreads(threads, [&](unsigned k) {
      for (std::size_t r; !stop && (r = nextRow++) < h;) {
        row(r);
        const std::size_t done = ++rowsDone;
        if (k == 0 && progress && !progress(from + span * static_cast<double>(done) / h, what)) stop = true;
      }
    });
    return !stop;
  }

 private:
  double diagonal_ = 0;
  unsigned threads_ = 1;  // (placingThreads)
  // The frame of `window`: the heights in metres there, voids filled (shadows) or at the lowest
  // height (holes, whose triangles are left out); the basis completed from the raster's centre.
  void placeWindow(const PixelWindow& window) {
    if (!complete_) {
      double lo = INFINITY, hi = -INFINITY;
      for (std::size_t i = 0; i < metres_.size(); ++i) {
        if (valid_[i]) lo = std::min(lo, metres_[i]), hi = std::max(hi, metres_[i]);
      }
      // Holes: voids at the lowest height (their triangles are left out); shadows: filled from
      // their rims over the whole raster, as localFrame fills them. (In place: observerAt reads
      // only the pixels with data.)
      if (holes_) {
        for (double& v : metres_) v = std::isnan(v) ? (lo <= hi ? lo : 0.0) : v;
      } else {
        fillVoids(metres_, dem_.width, dem_.height);
      }
      lo_ = lo, hi_ = hi;
    }
    std::vector<std::uint8_t> valid = sliceOf(valid_, window);
    // The frame's heights: the whole raster's are metres_ itself (no copy).
    const bool whole = window.width == dem_.width && window.height == dem_.height;
    windowHeights_ = whole ? std::vector<double>() : sliceOf(metres_, window);
    heights_ = whole ? std::span<const double>(metres_) : std::span<const double>(windowHeights_);
    // Viewsheds read the triangles from the grid (index(), guess(), walkMeets()); a point light's
    // attached shadow needs the mesh's.
    frame_ = flat_ ? gridFrame(basis_, window, std::move(valid))
                   : windowFrame(basis_, window, heights_, std::move(valid), !holes_, threads_);
    walkLow_.clear(), walkHigh_.clear();  // (walkBlocks: of the frame before)
    model_.reset();
    if (!complete_) {
      // The centre square's frame completes the basis (pixel size, the triangles' turn), as every
      // window's frame of the raster does (shadow_frame.hpp): this one when it holds the centre
      // and its vertices are placed.
      const PixelWindow centre{std::min((dem_.width - 1) / 2, dem_.width - 2),
                               std::min((dem_.height - 1) / 2, dem_.height - 2), 2, 2};
      const bool holds = centre.col >= window.col && centre.row >= window.row &&
                         centre.col + 2 <= window.col + window.width && centre.row + 2 <= window.row + window.height;
      // (Not a conditional expression: that would copy the whole frame.)
      if (holds && !frame_.mesh.vertices.empty()) {
        completeBasis(basis_, lo_, hi_, frame_);
      } else {
        completeBasis(basis_, lo_, hi_, windowFrame(basis_, centre, sliceOf(metres_, centre), sliceOf(valid_, centre)));
      }
      complete_ = true;
    }
    adoptBasis(frame_, basis_);
  }

  template <class T>
  std::vector<T> sliceOf(const std::vector<T>& all, const PixelWindow& win) const {
    std::vector<T> out;
    out.reserve(static_cast<std::size_t>(win.width) * win.height);
    for (int r = win.row; r < win.row + win.height; ++r) {
      const auto first = all.begin() + static_cast<std::ptrdiff_t>(static_cast<std::size_t>(r) * dem_.width + win.col);
      out.insert(out.end(), first, first + win.width);
    }
    return out;
  }

  // Whether every pixel on the window's sides inside the raster lies farther than reach from p.
  bool sidesBeyond(const Eigen::Vector3d& p, double reach) const {
    const LocalFrame& f = frame_;
    const Eigen::Vector3d up = f.upAt(p);
    const auto beyond = [&](int c, int r) {
      return horizontal(vertex(static_cast<std::size_t>(r) * f.width + c) - p, up) > reach;
    };
    const PixelWindow& win = f.window;
    for (int c = 0; c < f.width; ++c) {
      if (win.row > 0 && !beyond(c, 0)) return false;
      if (win.row + win.height < dem_.height && !beyond(c, f.height - 1)) return false;
    }
    for (int r = 0; r < f.height; ++r) {
      if (win.col > 0 && !beyond(0, r)) return false;
      if (win.col + win.width < dem_.width && !beyond(f.width - 1, r)) return false;
    }
    return true;
  }

  const DemTerrain& dem_;
  bool holes_ = true;
  FrameOptions options_;
  bool complete_ = false;
  double lo_ = 0, hi_ = 0;  // the height range of the pixels with data (metres)
  FrameBasis basis_;
  LocalFrame frame_;
  // Heights in metres over the whole raster: voids NaN until the frame is first placed, then at
  // the heights that frame places there (filled for shadows, the lowest for holes).
  std::vector<double> metres_;
  std::vector<std::uint8_t> valid_;
  // The frame's heights in metres (metres_ for the whole raster, else windowHeights_), and for a
  // flat viewshed's frame, its placement: frame_ then has no vertices until index() needs them.
  std::vector<double> windowHeights_;
  std::span<const double> heights_;
  std::optional<FlatPlacement> flat_;
  IndexOptions indexOptions_;
  std::unique_ptr<CartesianIndex> index_;
  // Each inner triangle's number in the raster rule, and back (index()).
  std::vector<std::uint32_t> squareOf_, triangleAt_;
  // walkBlocks(): squares a block's side, and the blocks' height ranges.
  static constexpr int kWalkBlock = 8;
  std::size_t walkBlocksAcross_ = 0;
  std::vector<double> walkLow_, walkHigh_;
  // model(): the observer's, and the border's triangles by ring cell.
  std::unique_ptr<Model> model_;
  std::vector<std::vector<std::uint32_t>> ring_[4];  // by walk::Side
};

// Before lines of sight go through the quadtree: its memory, unless the job's estimate counted
// it (loadDem's: a job estimated for the sweep can meet an observer the sweep cannot take, which
// `unswept` says).
// `frame` is what the quadtree is built over (a window round the observer within a maximum
// distance).
void requireQuadtree(const DemTerrain& dem, const LocalFrame& frame, bool unswept) {
  const std::uint64_t w = static_cast<std::uint64_t>(frame.width), h = static_cast<std::uint64_t>(frame.height);
  const std::uint64_t vertices = w * h, triangles = w > 1 && h > 1 ? 2 * (w - 1) * (h - 1) : 0;
  if (dem.estimatedBytes >= memory::kProcessBase + memory::kLinesOfSight.bytes(vertices, triangles)) return;
  memory::require(dem.path + ": lines of sight through the quadtree" +
                      (unswept ? std::string(" (an observer or light the sweep and the walk cannot take: on the "
                                             "surface, outside the outermost pixel centres, or on a raster too far "
                                             "from flat to walk)")
                               : std::string()),
                  memory::kLinesOfSight, vertices, triangles);
}

unsigned threadsOr(unsigned threads) {
  return threads ? threads : std::max(1u, std::min(8u, std::thread::hardware_concurrency()));
}

}  // namespace

namespace {

Viewshed viewshedOf(const DemTerrain& dem, std::vector<double>* takeHeights, const ViewshedOptions& o,
                    const Progress& progress, unsigned threads) {
  checkHeight("observer height", o.observerHeight);
  checkHeight("target height", o.targetHeight);
  checkMetres("maximum distance", o.maxDistance);
  Sightlines sight(dem, o.frame, o.index, progress, /*holes=*/true, takeHeights);
  sight.placingThreads(threadsOr(threads));
  Viewshed out;
  const Sightlines::Placed observer = sight.observerAt(o.observerX, o.observerY, o.observerHeight, "the observer");
  out.observer = observer.point, out.surface = observer.surface;
  // Within a maximum distance only the pixels around the observer are placed, and only the
  // triangles that reach within it can block (a segment between two points of the disc stays in
  // it, seen from above): those whose corners all lie within it and a triangle's extent (two pixel
  // diagonals) more.
  sight.place(&observer, o.maxDistance);
  if (o.refraction != 0) {
    if (!std::isfinite(o.refraction) || o.refraction <= -1 || o.refraction >= 1) {
      throw Error("the refraction coefficient must be between -1 and 1 (0.13 is the usual one for the Earth), got " +
                  number(o.refraction));
    }
    if (!sight.frame().body.ellipsoid) {
      throw Error(
          "refraction bends lines of sight over a curved body; a flat frame has no curvature to bend them over");
    }
    sight.refract(out.observer, o.refraction);
  }
  const LocalFrame& f = sight.frame();
  out.frameDescription = f.description;
  // Pixels with data outside the placed window are beyond the distance.
  const auto& valid = sight.valid();
  out.sight.assign(valid.size(), Sight::NoData);
  for (std::size_t i = 0; i < valid.size(); ++i) {
    if (valid[i] && o.maxDistance > 0) out.sight[i] = Sight::OutOfRange;
  }
  // (Counted once at the end: a count shared by the threads would be a contended atomic a pixel.)
  const auto visit = [&](std::size_t i, Sight s) { out.sight[i] = s; };
  bool finished = false;
  if (o.sweep && sight.sweepable(observer, o.observerHeight)) {
    sweep::Counts counts;
    finished = sight.sweepLook(observer, o.observerHeight, o.targetHeight, o.maxDistance, threadsOr(threads), progress,
                               0.05, 0.95, visit, counts);
    out.swept = counts.decided;
    out.method = "walk";
  } else if (o.sweep && sight.walkable(observer, o.observerHeight) && sight.model(observer, threadsOr(threads))) {
    // On an ellipsoid: each line of sight walked over the squares under it (no quadtree to build).
    if (progress && !progress(0.1, "testing lines of sight")) throw Error("viewshed cancelled");
    finished = sight.walkLook(observer, o.targetHeight, o.maxDistance, threadsOr(threads), progress, 0.1, 0.9, visit);
    out.method = "walk";
  } else {
    out.method = "quadtree";
    requireQuadtree(dem, f, o.sweep);
    if (progress && !progress(0.05, "building the quadtree")) throw Error("viewshed cancelled");
    const double diagonal = std::max(sight.diagonal(), std::hypot(f.pixelSizeX, f.pixelSizeY));
    sight.index(out.observer, f.upAt(out.observer), o.maxDistance > 0 ? o.maxDistance + 2 * diagonal : 0.0);
    finished = sight.look(out.observer, o.observerHeight, o.targetHeight, o.maxDistance, threadsOr(threads), progress,
                          0.1, 0.9, visit);
  }
  if (!finished) throw Error("viewshed cancelled");
  for (const Sight s : out.sight) {
    out.visible += s == Sight::Visible;
    out.tested += s == Sight::Visible || s == Sight::Hidden;
  }
  out.oneByOne = out.tested - std::min(out.tested, out.swept);
  if (progress) progress(1.0, "done");
  return out;
}

}  // namespace

Viewshed viewshed(const DemTerrain& dem, const ViewshedOptions& o, const Progress& progress, unsigned threads) {
  return viewshedOf(dem, nullptr, o, progress, threads);
}

Viewshed viewshed(DemTerrain&& dem, const ViewshedOptions& o, const Progress& progress, unsigned threads) {
  return viewshedOf(dem, &dem.heights, o, progress, threads);
}

CumulativeViewshed cumulativeViewshed(const DemTerrain& dem, std::span<const Observer> observers,
                                      const CumulativeOptions& o, const Progress& progress, unsigned threads) {
  checkHeight("target height", o.targetHeight);
  checkMetres("maximum distance", o.maxDistance);
  if (observers.empty()) throw Error("no observers given");
  if (o.which && observers.size() > kMaxWhich) {
    throw Error("which observers see each pixel is kept for at most " + std::to_string(kMaxWhich) +
                " observers (a bit each), not " + std::to_string(observers.size()));
  }
  Sightlines sight(dem, o.frame, o.index, progress);
  sight.placingThreads(threadsOr(threads));
  sight.place();
  const LocalFrame& f = sight.frame();
  std::vector<Sightlines::Placed> placed;
  placed.reserve(observers.size());
  for (std::size_t k = 0; k < observers.size(); ++k) {
    const Observer& ob = observers[k];
    const std::string what = ob.name.empty() ? "observer " + std::to_string(k + 1) : ob.name;
    checkHeight(what + " height", ob.height);
    placed.push_back(sight.observerAt(ob.x, ob.y, ob.height, what));
  }
  CumulativeViewshed out;
  const std::size_t n = f.pixelCount();
  out.count.assign(n, 0);
  if (o.which) out.which.assign(n, 0);
  out.valid.assign(f.valid.begin(), f.valid.end());
  out.frameDescription = f.description;
  const unsigned workers = threadsOr(threads);
  bool indexed = false;
  for (std::size_t k = 0; k < observers.size(); ++k) {
    const double from = 0.1 + 0.9 * static_cast<double>(k) / observers.size();
    const auto visit = [&](std::size_t i, Sight s) {
      if (s != Sight::Visible) return;  // (a pixel is one thread's)
      ++out.count[i];
      if (o.which) out.which[i] |= std::uint64_t{1} << k;
    };
    bool finished = false;
    if (o.sweep && sight.sweepable(placed[k], observers[k].height)) {
      sweep::Counts counts;
      finished = sight.sweepLook(placed[k], observers[k].height, o.targetHeight, o.maxDistance, workers, progress, from,
                                 0.9 / observers.size(), visit, counts);
    } else if (o.sweep && sight.walkable(placed[k], observers[k].height) && sight.model(placed[k], workers)) {
      finished = sight.walkLook(placed[k], o.targetHeight, o.maxDistance, workers, progress, from,
                                0.9 / observers.size(), visit);
    } else {
      if (!indexed) {
        requireQuadtree(dem, f, o.sweep);
        if (progress && !progress(from, "building the quadtree")) throw Error("viewshed cancelled");
        // One quadtree for every observer: the whole terrain (each observer's maximum distance
        // is checked per pixel).
        sight.index(Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ(), 0.0);
        indexed = true;
      }
      finished = sight.look(placed[k].point, observers[k].height, o.targetHeight, o.maxDistance, workers, progress,
                            from, 0.9 / observers.size(), visit);
    }
    if (!finished) throw Error("viewshed cancelled");
  }
  if (progress) progress(1.0, "done");
  return out;
}

std::vector<Light> pointLightMask(const DemTerrain& dem, const PointLightOptions& o, const Progress& progress,
                                  unsigned threads) {
  if (!std::isfinite(o.x) || !std::isfinite(o.y) || !std::isfinite(o.height)) {
    throw Error("the light's position must be finite, got " + number(o.x) + ", " + number(o.y) + ", " +
                number(o.height));
  }
  if (o.aboveSurface && !(o.height > 0)) {
    throw Error("the light's height above the surface must be more than 0 m, got " + number(o.height));
  }
  if (std::fabs(o.height) > kMaxHeight) {
    throw Error("the light's height must be within 1e9 m (beyond any terrain), got " + number(o.height));
  }
  Sightlines sight(dem, o.frame, o.index, progress, /*holes=*/false);
  sight.placingThreads(threadsOr(threads));
  sight.place();
  const LocalFrame& f = sight.frame();
  const Sightlines::Placed lamp = o.aboveSurface ? sight.observerAt(o.x, o.y, o.height, "the light") : [&] {
    const auto [col, row] = dem.pixelOf(dem.turnedOnto(o.x), o.y);
    return Sightlines::Placed{sight.pointAt(col, row, o.height), NAN, col, row};
  }();
  const Eigen::Vector3d light = lamp.point;
  // Each segment walked over the squares under it where the light stands inside the outermost
  // centres' lines (on an ellipsoid, modelled: model()); else through the quadtree.
  const bool walk = o.walk && sight.walkableFrom(lamp) && (!f.body.ellipsoid || sight.model(lamp, threadsOr(threads)));
  if (!walk) {
    requireQuadtree(dem, f, o.walk);
    if (progress && !progress(0.05, "building the quadtree")) throw Error("shadow computation cancelled");
    sight.index(Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ(), 0.0);
  } else if (!f.body.ellipsoid) {
    sight.walkBlocks(threadsOr(threads));
  }
  // How each triangle faces the light (its plane's side), for attached shadow: the light
  // arriving from below a pixel's own surface.
  const Mesh& mesh = f.mesh;
  std::vector<std::uint8_t> facing(mesh.polygonCount());
  for (std::size_t t = 0; t < facing.size(); ++t) {
    const auto c = mesh.polygon(t);
    facing[t] =
        shadow::facingOf(f, c, (light - mesh.vertices[c[0]]).normalized(), f.body.ellipsoid ? f.gridWinding : 0);
  }
  std::vector<Light> out(f.pixelCount(), Light::NoData);
  const int w = f.width;
  const bool finished = sight.inRows(threadsOr(threads), progress, 0.1, 0.9, "testing pixels", [&](std::size_t r) {
    std::uint32_t blocker = CartesianIndex::kNoPolygon;  // the last pixel's, along the row
    std::int64_t blockerSquare = -1;                     // (the walk's)
    for (std::size_t i = r * w; i < (r + 1) * w; ++i) {
      if (!f.valid[i]) continue;
      std::uint32_t ring[RasterGrid::kMaxRing];
      bool closed = false;
      const int count = f.grid.ring(static_cast<int>(r), static_cast<int>(i - r * w), ring, closed);
      const Eigen::Vector3d& p = mesh.vertices[i];
      const bool attached = shadow::attachedShadow(f, std::span<const std::uint32_t>(ring, count), closed,
                                                   static_cast<std::uint32_t>(i), light - p, facing.data());
      const auto vertex = static_cast<std::uint32_t>(i);
      const bool cast = !attached && (walk ? sight.walkBlocked(lamp, p, i, vertex, blockerSquare)
                                           : sight.meets(blocker, light, p, vertex));
      out[i] = attached || cast ? Light::Shadow : Light::Lit;
    }
  });
  if (!finished) throw Error("shadow computation cancelled");
  if (progress) progress(1.0, "done");
  return out;
}

}  // namespace qota
