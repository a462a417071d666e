#include "qota/shadow.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <memory>
#include <optional>
#include <span>
#include <thread>

#include "float_bounds.hpp"
#include "qota/error.hpp"
#include "qota/predicates.hpp"

namespace qota {
namespace {

// Triangles around each vertex, as offsets into one list, for a frame whose mesh is not
// localFrame's grid.
struct VertexStar {
  std::vector<std::uint32_t> start, tris;
  VertexStar(const Mesh& mesh) : start(mesh.vertices.size() + 1, 0) {
    for (std::uint32_t idx : mesh.indices) ++start[idx + 1];
    for (std::size_t i = 1; i < start.size(); ++i) start[i] += start[i - 1];
    tris.resize(mesh.indices.size());
    std::vector<std::uint32_t> fill(start.begin(), start.end() - 1);
    for (std::size_t t = 0; t < mesh.polygonCount(); ++t) {
      for (std::uint32_t idx : mesh.polygon(t)) tris[fill[idx]++] = static_cast<std::uint32_t>(t);
    }
  }
};

// How a triangle faces the light (facingOf): kOccluder when it can cast a shadow on a cell that
// is not in attached shadow. Such a cell's ray starts into the open air, so the first terrain it
// meets, it enters, and it enters through a triangle whose normal points away from the light. Both
// searches take these alone (and, to stay on the safe side of rounding, those within 1e-9 of
// edge-on): the same answers as with every triangle, for a fraction of the work. kFacesAway: the
// light strictly behind it, for attached shadow. The normal is turned up: the frame's +z, or on an
// ellipsoid the body's normal at the triangle's first corner (the DEM's corner order may be
// either way round); `winding` (+1 or -1) says it for a grid, whose triangles all turn alike.
constexpr std::uint8_t kOccluder = 1, kFacesAway = 2;
std::uint8_t facingOf(const LocalFrame& frame, std::span<const std::uint32_t> c, const Eigen::Vector3d& light,
                      int winding) {
  const Mesh& mesh = frame.mesh;
  const Eigen::Vector3d& a = mesh.vertices[c[0]];
  const Eigen::Vector3d n = (mesh.vertices[c[1]] - a).cross(mesh.vertices[c[2]] - a);
  const double up = winding != 0 ? winding : frame.body.ellipsoid ? n.dot(frame.upAt(a)) : n.z();
  const double d = up >= 0 ? n.dot(light) : -n.dot(light);
  return static_cast<std::uint8_t>((d <= 0 || d * d <= 1e-18 * n.squaredNorm() ? kOccluder : 0) |
                                   (d < 0 ? kFacesAway : 0));
}

// Attached shadow: the light arrives from below the surface at vertex i. Seen from above (along
// the body's up at i), the light's horizontal direction leaves i through one of its own triangles
// (exactly: the one whose corner sector at i contains that direction); the vertex is in attached
// shadow when the light rises more slowly than that triangle does in that direction, which is
// when the triangle faces away from the light. A light straight up, or a direction leaving the
// terrain (across an edge of the surface), is not attached shadow.
// ring: the triangles around i in increasing order (the first whose sector holds the direction
// decides); closed: they go all the way round, so that when all of them face away, whichever
// holds the direction does. facing: facingOf every triangle.
bool attachedShadow(const LocalFrame& frame, std::span<const std::uint32_t> ring, bool closed, std::uint32_t i,
                    const Eigen::Vector3d& light, const std::uint8_t* facing) {
  unsigned away = 0;
  for (const std::uint32_t polygon : ring) away += (facing[polygon] & kFacesAway) != 0;
  if (away == 0) return false;
  const Mesh& mesh = frame.mesh;
  const Eigen::Vector3d& p = mesh.vertices[i];
  // Seen from above: the frame's x, y as they are (exact), or on an ellipsoid the vertex's tangent
  // plane, coordinates relative to the vertex.
  Eigen::Vector3d e1(1, 0, 0), e2(0, 1, 0);
  Point2 p2{p.x(), p.y()}, s2{p.x() + light.x(), p.y() + light.y()};
  if (frame.body.ellipsoid) {
    const Eigen::Vector3d up = frame.upAt(p);
    e1 = up.unitOrthogonal();
    e2 = up.cross(e1);
    p2 = {0, 0};
    s2 = {light.dot(e1), light.dot(e2)};
  }
  if (s2.u == p2.u && s2.v == p2.v) return false;  // the light straight up (or down)
  if (closed && away == ring.size()) return true;
  const auto seen = [&](std::uint32_t k) -> Point2 {
    const Eigen::Vector3d& v = mesh.vertices[k];
    if (!frame.body.ellipsoid) return {v.x(), v.y()};
    const Eigen::Vector3d d = v - p;
    return {d.dot(e1), d.dot(e2)};
  };
  for (const std::uint32_t polygon : ring) {
    const auto t = mesh.polygon(polygon);
    // The other two corners, in counter-clockwise order around i.
    std::uint32_t a = t[0] == i ? t[1] : t[1] == i ? t[2] : t[0];
    std::uint32_t b = t[0] == i ? t[2] : t[1] == i ? t[0] : t[1];
    Point2 a2 = seen(a), b2 = seen(b);
    const int orientation = orient2dSign(p2, a2, b2);
    if (orientation == 0) continue;
    if (orientation < 0) std::swap(a, b), std::swap(a2, b2);
    if (orient2dSign(p2, a2, s2) < 0 || orient2dSign(p2, s2, b2) < 0) continue;  // not this sector
    return (facing[polygon] & kFacesAway) != 0;
  }
  return false;
}

// Runs body(0) .. body(count - 1), each on its own thread (body(0) on this one).
template <class Body>
void inThreads(unsigned count, const Body& body) {
  std::vector<std::thread> pool;
  for (unsigned k = 1; k < count; ++k) pool.emplace_back([&body, k] { body(k); });
  body(0);
  for (auto& t : pool) t.join();
}

// Candidate occluders for the light rays of a DEM's vertices, found without a light-frame tree.
// Seen from above, every ray runs along the sun's azimuth g, at a constant offset c across it,
// rising tan(altitude) per metre of a = position along g: it keeps w = z - a tan(altitude)
// constant. (c and w are coordinates across the light: a ray is a point in them.) A triangle T
// that the ray from P meets, at a point ahead of P, has c(P) in T's range of c, w(P) in T's range
// of w (w is linear over T, so that is its corners' range) and a(P) at most T's largest a. So the
// occluding triangles are binned into strips of c (one pixel wide; a triangle goes into every
// strip its c range meets), each strip sorted by the triangles' largest a, and a ray searches its
// strip from a(P) on: a binary search, then a scan that skips blocks of 8 and 64 triangles whose
// largest w is below w(P) (and stops when no later block reaches it), testing the other ranges
// per triangle. Each candidate takes the shadow quadtree's exact test (mappedTriangleAbove), and
// every triangle that test can accept is a candidate (the margins are far above the rounding), so
// the mask is the quadtree's.
class HorizonStrips {
 public:
  // The mesh's occluding triangles for a light that is not straight overhead; facing: gets
  // facingOf every triangle, found on the way. Built by `threads` threads, with the same result
  // for any number (up to the order of equal entries, which no search can tell).
  HorizonStrips(const LocalFrame& frame, const Eigen::Vector3d& light, double stripWidth,
                std::vector<std::uint8_t>& facing, unsigned threads, int winding) {
    const Mesh& mesh = frame.mesh;
    const double horizontal = light.head<2>().norm();
    g_ = light.head<2>() / horizontal;
    tan_ = light.z() / horizontal;
    const unsigned parts = std::max(1u, threads);
    // Each occluder's ranges, rounded outward; and the size of the coordinates. By parts of the
    // mesh, one per thread.
    const std::size_t polygons = mesh.polygonCount();
    facing.resize(polygons);
    std::vector<std::vector<Entry>> spans(parts);
    std::vector<double> xyMax(parts, 0), zMax(parts, 0);
    inThreads(parts, [&](unsigned part) {
      const std::size_t from = polygons * part / parts, to = polygons * (part + 1) / parts;
      std::vector<Entry>& out = spans[part];
      out.reserve(to - from);  // (only the pages written are ever touched)
      double xy = 0, z = 0;
      for (std::size_t p = from; p < to; ++p) {
        const auto corners = mesh.polygon(p);
        facing[p] = facingOf(frame, corners, light, winding);
        if (!(facing[p] & kOccluder)) continue;
        double cl = INFINITY, ch = -INFINITY, ah = -INFINITY, wl = INFINITY, wh = -INFINITY;
        for (std::uint32_t k : corners) {
          const Eigen::Vector3d& v = mesh.vertices[k];
          const double a = along(v), c = across(v), w = v.z() - a * tan_;
          cl = std::min(cl, c), ch = std::max(ch, c), ah = std::max(ah, a);
          wl = std::min(wl, w), wh = std::max(wh, w);
          xy = std::max(xy, std::max(std::fabs(v.x()), std::fabs(v.y()))), z = std::max(z, std::fabs(v.z()));
        }
        // Field by field: an Entry built whole was stored in halves and reloaded whole (a stall).
        Entry& e = out.emplace_back();
        e.aHi = floatAbove(ah), e.wHi = floatAbove(wh), e.wLo = floatBelow(wl);
        e.cLo = floatBelow(cl), e.cHi = floatAbove(ch), e.tri = static_cast<std::uint32_t>(p);
      }
      xyMax[part] = xy, zMax[part] = z;
    });
    // Margins: a millionth of the coordinates' size, where rounding is below a trillionth (the
    // cells are the same grid's vertices, of the same size).
    const double xy = *std::max_element(xyMax.begin(), xyMax.end()), z = *std::max_element(zMax.begin(), zMax.end());
    marginA_ = 1e-6 * (2 * xy + 1);
    marginW_ = 1e-6 * (z + 2 * xy * tan_ + 1);
    cLo_ = INFINITY;
    double cHi = -INFINITY;
    for (const auto& part : spans) {
      for (const Entry& e : part) cLo_ = std::min(cLo_, e.cLo - marginA_), cHi = std::max(cHi, e.cHi + marginA_);
    }
    if (!(cLo_ <= cHi)) return;  // no occluder
    // One pixel a strip, but no more strips than a few per cell (a DEM of wild heights can spread
    // its occluders far wider than the cells): the width only tunes the search, never its answer.
    const double maxStrips = 4.0 * static_cast<double>(frame.cellCount()) + 1024;
    perWidth_ = std::min(1 / stripWidth, maxStrips / (cHi - cLo_));
    const std::size_t strips = strip(cHi) + 1;
    const auto stripsOf = [&](const Entry& e, std::size_t& lo, std::size_t& hi) {
      lo = strip(e.cLo - marginA_), hi = std::min(strips - 1, strip(e.cHi + marginA_));
    };
    // A counting sort into the strips: each part's entries of a strip go after the earlier
    // parts'. Each strip is padded to whole superblocks (64) with entries no ray reaches.
    std::vector<std::vector<std::uint64_t>> fill(parts, std::vector<std::uint64_t>(strips, 0));
    inThreads(parts, [&](unsigned part) {
      for (const Entry& e : spans[part]) {
        std::size_t lo, hi;
        stripsOf(e, lo, hi);
        for (std::size_t k = lo; k <= hi; ++k) ++fill[part][k];
      }
    });
    start_.assign(strips + 1, 0);
    std::vector<std::uint64_t> used(strips);
    for (std::size_t k = 0; k < strips; ++k) {
      std::uint64_t at = start_[k];
      for (unsigned part = 0; part < parts; ++part) {
        const std::uint64_t n = fill[part][k];
        fill[part][k] = at;
        at += n;
      }
      used[k] = at;
      start_[k + 1] = start_[k] + (at - start_[k] + kSuper - 1) / kSuper * kSuper;
    }
    entryCount_ = start_[strips];
    entries_.reset(new Entry[entryCount_]);  // uninitialized: every one is written below
    inThreads(parts, [&](unsigned part) {
      for (const Entry& e : spans[part]) {
        std::size_t lo, hi;
        stripsOf(e, lo, hi);
        for (std::size_t k = lo; k <= hi; ++k) entries_[fill[part][k]++] = e;
      }
    });
    spans = {};
    // Each strip by largest a, then its padding; the largest w of every block (8) and superblock
    // (64), and of every superblock with all after it in the strip. By ranges of strips.
    blockW_.assign(entryCount_ / kBlock, -INFINITY);
    superW_.assign(entryCount_ / kSuper, -INFINITY);
    laterW_.assign(entryCount_ / kSuper, -INFINITY);
    inThreads(parts, [&](unsigned part) {
      for (std::size_t k = strips * part / parts; k < strips * (part + 1) / parts; ++k) {
        Entry* E = entries_.get();
        std::sort(E + start_[k], E + used[k], [](const Entry& x, const Entry& y) { return x.aHi < y.aHi; });
        std::fill(E + used[k], E + start_[k + 1], Entry{INFINITY, -INFINITY, INFINITY, INFINITY, -INFINITY, kNone});
        float later = -INFINITY;
        for (std::uint64_t sb = start_[k + 1] / kSuper; sb-- > start_[k] / kSuper;) {
          for (std::uint64_t e = sb * kSuper; e < (sb + 1) * kSuper; ++e) {
            blockW_[e / kBlock] = std::max(blockW_[e / kBlock], E[e].wHi);
            superW_[sb] = std::max(superW_[sb], E[e].wHi);
          }
          later = std::max(later, superW_[sb]);
          laterW_[sb] = later;
        }
      }
    });
  }

  std::size_t stripCount() const { return start_.empty() ? 0 : start_.size() - 1; }
  // The strip of the ray from p; stripCount() when no strip holds it.
  std::size_t stripOf(const Eigen::Vector3d& p) const {
    const double c = across(p);
    if (!(c >= cLo_) || start_.empty()) return stripCount();
    return std::min(strip(c), stripCount());
  }

  // Whether test(t) holds for a candidate t (a mesh polygon) of the ray from p. hint: where the
  // last search of this thread ended (any value will do; a nearby one is faster).
  template <class Test>
  bool anyAlong(const Eigen::Vector3d& p, std::uint64_t& hint, Test&& test) const {
    const std::size_t k = stripOf(p);
    if (k >= stripCount()) return false;
    const double c = across(p), a = along(p), w = p.z() - a * tan_;
    const double wFrom = w - marginW_, wTo = w + marginW_, aFrom = a - marginA_;
    const double cPlus = c + marginA_, cMinus = c - marginA_;
    const Entry* E = entries_.get();
    const std::uint64_t end = start_[k + 1];
    // First entry with aHi >= aFrom: a few steps from the hint when it is in this strip (the
    // cells of a strip come nearly in order of a, a pixel or so apart: one mispredicted branch
    // where a binary search has several), else (or when that is far) a binary search.
    const auto before = [&](const Entry& x) { return x.aHi < aFrom; };
    std::uint64_t lo = start_[k], hi = end, e;
    if (hint >= lo && hint < hi) {
      constexpr std::uint64_t kSteps = 16;
      if (before(E[hint])) {
        for (lo = hint + 1; lo < hi && lo - hint < kSteps && before(E[lo]);) ++lo;
        e = lo < hi && lo - hint == kSteps ? static_cast<std::uint64_t>(std::partition_point(E + lo, E + hi, before) - E) : lo;
      } else {
        for (hi = hint; hi > lo && hint - hi < kSteps && !before(E[hi - 1]);) --hi;
        e = hi > lo && hint - hi == kSteps ? static_cast<std::uint64_t>(std::partition_point(E + lo, E + hi, before) - E) : hi;
      }
    } else {
      e = static_cast<std::uint64_t>(std::partition_point(E + lo, E + hi, before) - E);
    }
    hint = e;
    if (e >= end || !(laterW_[e / kSuper] >= wFrom)) return false;
    for (;;) {
      for (const std::uint64_t blockEnd = (e / kBlock + 1) * kBlock; e < blockEnd; ++e) {
        const Entry& x = E[e];
        if (x.wHi >= wFrom && x.wLo <= wTo && x.cLo <= cPlus && x.cHi >= cMinus && test(x.tri)) return true;
      }
      // At a block boundary: the next block in this superblock that reaches the ray, else the
      // next superblock that does (none: nothing later does).
      while (e % kSuper != 0 && !(blockW_[e / kBlock] >= wFrom)) e += kBlock;
      if (e % kSuper != 0) continue;
      if (e >= end || !(laterW_[e / kSuper] >= wFrom)) return false;
      while (!(superW_[e / kSuper] >= wFrom)) e += kSuper;
      while (!(blockW_[e / kBlock] >= wFrom)) e += kBlock;
    }
  }

 private:
  static constexpr std::uint32_t kNone = 0xffffffffu;
  static constexpr std::uint64_t kBlock = 8, kSuper = 64;
  struct Entry {
    float aHi, wHi, wLo, cLo, cHi;  // rounded outward
    std::uint32_t tri;
  };
  double along(const Eigen::Vector3d& v) const { return v.x() * g_.x() + v.y() * g_.y(); }
  double across(const Eigen::Vector3d& v) const { return v.y() * g_.x() - v.x() * g_.y(); }
  // Monotone in c, which is all the binning needs (a multiplication, not a division).
  std::size_t strip(double c) const { return static_cast<std::size_t>((c - cLo_) * perWidth_); }

  Eigen::Vector2d g_;
  double tan_ = 0, marginA_ = 0, marginW_ = 0, cLo_ = 0, perWidth_ = 1;
  std::vector<std::uint64_t> start_;
  std::unique_ptr<Entry[]> entries_;
  std::uint64_t entryCount_ = 0;
  std::vector<float> blockW_, superW_, laterW_;
};

}  // namespace

double shadowReach(const LocalFrame& frame, const Eigen::Vector3d& towardLight) {
  const Eigen::Vector3d d = towardLight.normalized();
  const double horizontal = d.head<2>().norm();
  if (d.z() <= 0) return INFINITY;
  return (frame.maxHeight - frame.minHeight) * horizontal / d.z();
}

std::vector<Light> shadowMask(const LocalFrame& frame, const Eigen::Vector3d& towardLight,
                              const TerrainOptions& options, const Progress& progress,
                              unsigned threadCount, ShadowSearch search) {
  const auto& vertices = frame.mesh.vertices;
  const std::size_t cellCount = frame.cellCount();
  if (frame.valid.size() != cellCount || vertices.size() < cellCount) {
    throw Error("shadow mask: the frame's cells and vertices do not match its size");
  }
  std::vector<Light> out(cellCount, Light::NoData);
  const auto report = [&](double done, const char* message) {
    if (progress && !progress(done, message)) throw Error("shadow computation cancelled");
  };
  if (!towardLight.allFinite() || towardLight.squaredNorm() == 0) {
    throw Error("light direction must be a nonzero finite vector");
  }
  const Eigen::Vector3d light = towardLight.normalized();
  if (!frame.body.ellipsoid && light.z() <= 0) {
    // A flat frame with the light at or below the horizon: no direct light anywhere.
    for (std::size_t i = 0; i < cellCount; ++i) {
      if (frame.valid[i]) out[i] = Light::Shadow;
    }
    report(1.0, "light below the horizon");
    return out;
  }

  // The strips need a horizontal direction to the light (not straight overhead), and keep their
  // ranges in floats: coordinates far beyond any planet's (localFrame refuses heights beyond
  // 1e9 m; a frame made by hand may hold anything) take the quadtree instead.
  double extent = 0;
  for (const Eigen::Vector3d& v : vertices) extent = std::max(extent, v.cwiseAbs().maxCoeff());
  const bool useStrips = search == ShadowSearch::Strips && light.head<2>().norm() > 1e-6 && extent < 1e30;
  const unsigned threads =
      threadCount ? threadCount : std::max(1u, std::min(8u, std::thread::hardware_concurrency()));
  // The light's direction of travel is the "gravity" of the shadow quadtree's frame: "above" a
  // point means toward the light. The strips decide their candidates in the same frame.
  const CartesianMapping mapping(-light);
  // The triangles around each vertex: arithmetic on localFrame's own grid, else a table.
  const bool gridMesh = frame.gridMesh && frame.grid.width() == frame.width && frame.grid.height() == frame.height &&
                        vertices.size() == frame.grid.vertexCount() &&
                        frame.mesh.polygonCount() == frame.grid.triangleCount();
  std::optional<VertexStar> star;
  if (!gridMesh) star.emplace(frame.mesh);
  // On an ellipsoid a grid's triangles all turn alike (facingOf); else each is looked at.
  const int winding = frame.body.ellipsoid && gridMesh ? frame.gridWinding : 0;

  // Two passes over the cells, each shared out to `workers` threads in groups (the calling thread
  // reports progress), after every triangle's facing is known: attached shadow (and the body's
  // own shadow) by rows, reading each vertex's ring in memory order; then cast shadow for the
  // cells still lit, by rows through the quadtree or by strips through the strips (each strip's
  // cells in row order, so nearly in order of a: consecutive searches read the same few cache
  // lines of the same strip).
  const auto width = static_cast<std::size_t>(frame.width);
  std::atomic<std::size_t> cellsDone{0};
  std::atomic<bool> stop{false};
  const auto inParallel = [&](unsigned workers, std::size_t groups, const auto& cellsOf, const auto& body) {
    std::atomic<std::size_t> next{0};
    const auto work = [&](bool reporter) {
      for (std::size_t g; !stop && (g = next++) < groups;) {
        body(g);
        const std::size_t done = cellsDone += cellsOf(g);
        const double fraction = static_cast<double>(done) / static_cast<double>(2 * std::max<std::size_t>(1, cellCount));
        if (reporter && progress && !progress(0.3 + 0.7 * fraction, "testing cells")) stop = true;
      }
    };
    inThreads(workers, [&](unsigned k) { work(k == 0); });
  };
  const auto rowCells = [&](std::size_t) { return width; };
  std::vector<std::uint8_t> facing;  // facingOf every triangle
  const BodyRays bodyRays(frame, light);
  const auto attachedPass = [&](unsigned workers) {
    inParallel(workers, static_cast<std::size_t>(frame.height), rowCells, [&](std::size_t r) {
      for (std::size_t i = r * width; i < (r + 1) * width; ++i) {
        if (!frame.valid[i]) continue;
        std::uint32_t grid[RasterGrid::kMaxRing];
        bool closed = false;
        const std::span<const std::uint32_t> ring =
            gridMesh ? std::span<const std::uint32_t>(
                           grid, static_cast<std::size_t>(frame.grid.ring(static_cast<int>(r),
                                                                           static_cast<int>(i - r * width), grid, closed)))
                     : std::span<const std::uint32_t>(star->tris.data() + star->start[i], star->start[i + 1] - star->start[i]);
        const bool shadow = attachedShadow(frame, ring, closed, static_cast<std::uint32_t>(i), light, facing.data()) ||
                            (frame.body.ellipsoid && bodyRays.entersBody(vertices[i]));
        out[i] = shadow ? Light::Shadow : Light::Lit;
      }
    });
  };

  if (!useStrips) {
    report(0.0, "building the shadow quadtree");
    Mesh occluders;
    occluders.vertices = frame.mesh.vertices;
    facing.resize(frame.mesh.polygonCount());
    for (std::size_t t = 0; t < frame.mesh.polygonCount(); ++t) {
      const auto c = frame.mesh.polygon(t);
      facing[t] = facingOf(frame, c, light, winding);
      if (facing[t] & kOccluder) occluders.addTriangle(c[0], c[1], c[2]);
    }
    report(0.3, "testing cells");
    attachedPass(threads);
    if (occluders.polygonCount() > 0) {
      const TerrainIndex index(occluders, mapping, options);
      inParallel(threads, static_cast<std::size_t>(frame.height), rowCells, [&](std::size_t r) {
        for (std::size_t i = r * width; i < (r + 1) * width; ++i) {
          if (out[i] != Light::Lit) continue;
          const Eigen::Vector3d m = mapping.toMapped(vertices[i]);
          if (index.occludedAbove(m.x(), m.y(), m.z(), static_cast<std::uint32_t>(i))) out[i] = Light::Shadow;
        }
      });
    }
  } else {
    report(0.0, "sorting the occluders into strips");
    const HorizonStrips strips(frame, light, std::min(frame.pixelSizeX, frame.pixelSizeY), facing, threads, winding);
    report(0.3, "testing cells");
    attachedPass(threads);
    std::vector<std::uint32_t> stripOf(cellCount), order(cellCount);
    std::vector<std::uint64_t> start(strips.stripCount() + 2, 0);  // the last: cells in none
    for (std::size_t i = 0; i < cellCount; ++i) {
      stripOf[i] = static_cast<std::uint32_t>(strips.stripOf(vertices[i]));
      ++start[stripOf[i] + 1];
    }
    for (std::size_t g = 1; g < start.size(); ++g) start[g] += start[g - 1];
    std::vector<std::uint64_t> fill(start.begin(), start.end() - 1);
    for (std::size_t i = 0; i < cellCount; ++i) order[fill[stripOf[i]]++] = static_cast<std::uint32_t>(i);
    inParallel(threads, start.size() - 1, [&](std::size_t g) { return start[g + 1] - start[g]; }, [&](std::size_t g) {
      std::uint64_t hint = 0;
      for (std::uint64_t k = start[g]; k < start[g + 1]; ++k) {
        if (k + 8 < start[g + 1]) {  // a strip's cells are a row apart in memory
          __builtin_prefetch(&vertices[order[k + 8]]);
          __builtin_prefetch(&out[order[k + 8]]);
        }
        const std::uint32_t i = order[k];
        if (out[i] != Light::Lit) continue;
        const Eigen::Vector3d m = mapping.toMapped(vertices[i]);
        const auto occludes = [&](std::uint32_t t) {
          // A cell's own triangles meet its ray at the cell itself: never an occluder.
          const auto c = frame.mesh.polygon(t);
          if (c[0] == i || c[1] == i || c[2] == i) return false;
          return mappedTriangleAbove(mapping.toMapped(vertices[c[0]]), mapping.toMapped(vertices[c[1]]),
                                     mapping.toMapped(vertices[c[2]]), m.x(), m.y(), m.z());
        };
        if (strips.anyAlong(vertices[i], hint, occludes)) out[i] = Light::Shadow;
      }
    });
  }
  if (stop) throw Error("shadow computation cancelled");
  report(1.0, "done");
  return out;
}

}  // namespace qota
