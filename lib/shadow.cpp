#include "qota/shadow.hpp"

#include <Eigen/Geometry>
#include <GeographicLib/LocalCartesian.hpp>
#include <ogr_spatialref.h>

#include <atomic>
#include <cmath>
#include <future>
#include <memory>
#include <optional>
#include <span>
#include <thread>

#include "float_bounds.hpp"
#include "qota/error.hpp"
#include "qota/globe.hpp"
#include "qota/predicates.hpp"

namespace qota {
namespace {

constexpr double kDeg = M_PI / 180.0;

// A raster's axes are x = easting or longitude, y = northing or latitude (GDAL's convention for
// rasters), whatever the CRS's official axis order.
OGRSpatialReference rasterCrs(const DemTerrain& dem) {
  OGRSpatialReference srs;
  if (srs.importFromWkt(dem.crsWkt.c_str()) != OGRERR_NONE) {
    throw Error(dem.path + ": its coordinate reference system cannot be read");
  }
  srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  return srs;
}

// Fills NaN heights from their neighbours, rim inwards (onion peeling, as gdal_fillnodata does in
// spirit): each pass gives every void cell next to known cells the mean of those, until none is
// left. A raster with no data at all becomes flat at 0.
void fillVoids(std::vector<double>& z, int w, int h) {
  std::vector<std::size_t> todo;
  for (std::size_t i = 0; i < z.size(); ++i) {
    if (!std::isfinite(z[i])) todo.push_back(i);
  }
  std::vector<std::pair<std::size_t, double>> fills;
  while (!todo.empty()) {
    fills.clear();
    std::vector<std::size_t> still;
    for (std::size_t i : todo) {
      const int c = static_cast<int>(i % w), r = static_cast<int>(i / w);
      double sum = 0;
      int count = 0;
      for (int dr = -1; dr <= 1; ++dr) {
        for (int dc = -1; dc <= 1; ++dc) {
          const int cc = c + dc, rr = r + dr;
          if ((dr || dc) && cc >= 0 && rr >= 0 && cc < w && rr < h) {
            const double v = z[static_cast<std::size_t>(rr) * w + cc];
            if (std::isfinite(v)) sum += v, ++count;
          }
        }
      }
      if (count) {
        fills.push_back({i, sum / count});
      } else {
        still.push_back(i);
      }
    }
    if (fills.empty()) {  // nothing known anywhere
      for (std::size_t i : still) z[i] = 0;
      break;
    }
    for (const auto& [i, v] : fills) z[i] = v;
    todo.swap(still);
  }
}

}  // namespace

Eigen::Vector3d LocalFrame::towardSun(const SunPosition& sun) const {
  SunPosition inFrame = sun;
  inFrame.azimuth = sun.azimuth + trueNorthFromY;
  return towardSunEnu(inFrame);
}

LocalFrame localFrame(const DemTerrain& dem, bool flat, double pixelSize) {
  LocalFrame f;
  f.width = dem.width;
  f.height = dem.height;
  const std::size_t n = dem.mesh.vertices.size();
  // Heights with the voids filled (for occlusion only), and which cells have data.
  std::vector<double> z(n);
  f.valid.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    z[i] = dem.mesh.vertices[i].z();
    f.valid[i] = std::isfinite(z[i]);
  }
  fillVoids(z, dem.width, dem.height);
  // Every cell's two triangles, split as the DEM's (top-left to bottom-right diagonal).
  for (int r = 0; r + 1 < dem.height; ++r) {
    for (int c = 0; c + 1 < dem.width; ++c) {
      const auto tl = static_cast<std::uint32_t>(r * dem.width + c), tr = tl + 1;
      const auto bl = static_cast<std::uint32_t>(tl + dem.width), br = bl + 1;
      f.mesh.addTriangle(tl, bl, br);
      f.mesh.addTriangle(tl, br, tr);
    }
  }
  f.mesh.vertices.resize(n);
  f.gridMesh = true;
  const double cc = (dem.width - 1) / 2.0, cr = (dem.height - 1) / 2.0;
  const auto centre = dem.pixelCentre(cc, cr);

  if (dem.crsWkt.empty()) {
    if (!(pixelSize > 0)) {
      throw Error(dem.path + ": the raster has no coordinate reference system, so the size of its "
                  "pixels in metres is unknown; give it with --pixel-size METRES");
    }
    // Pixel grid, rows running south.
    for (std::size_t i = 0; i < n; ++i) {
      const double c = static_cast<double>(i % dem.width), r = static_cast<double>(i / dem.width);
      f.mesh.vertices[i] = {(c - cc) * pixelSize, -(r - cr) * pixelSize, z[i]};
    }
    f.description = "pixel grid, " + std::to_string(pixelSize) + " m per pixel (no CRS)";
  } else {
    const OGRSpatialReference srs = rasterCrs(dem);
    if (srs.IsGeographic()) {
      double a = 0, fl = 0;
      demEllipsoid(dem, a, fl);
      const double lon0 = centre[0], lat0 = centre[1];
      f.geographicLocation = true;
      f.centreLon = lon0;
      f.centreLat = lat0;
      if (flat) {
        // Longitude and latitude scaled linearly by the ellipsoid's radii of curvature at the
        // centre: no curvature.
        const double e2 = fl * (2 - fl), s = std::sin(lat0 * kDeg);
        const double w = std::sqrt(1 - e2 * s * s);
        const double nRad = a / w, mRad = a * (1 - e2) / (w * w * w);
        for (std::size_t i = 0; i < n; ++i) {
          const Eigen::Vector3d& p = dem.mesh.vertices[i];
          f.mesh.vertices[i] = {(p.x() - lon0) * kDeg * nRad * std::cos(lat0 * kDeg),
                                (p.y() - lat0) * kDeg * mRad, z[i]};
        }
        f.description = "flat east-north-up metres around the centre (--flat)";
      } else {
        const GeographicLib::LocalCartesian local(lat0, lon0, 0, GeographicLib::Geocentric(a, fl));
        for (std::size_t i = 0; i < n; ++i) {
          const Eigen::Vector3d& p = dem.mesh.vertices[i];
          Eigen::Vector3d& q = f.mesh.vertices[i];
          local.Forward(p.y(), p.x(), z[i], q.x(), q.y(), q.z());
        }
        f.description = "east-north-up metres on the ellipsoid (a = " + std::to_string(a) +
                        " m), tangent at the centre";
      }
    } else {
      const double unit = srs.GetLinearUnits();
      for (std::size_t i = 0; i < n; ++i) {
        const Eigen::Vector3d& p = dem.mesh.vertices[i];
        f.mesh.vertices[i] = {(p.x() - centre[0]) * unit, (p.y() - centre[1]) * unit, z[i]};
      }
      f.description = "projected grid metres";
      // Where the centre is, and where true north points on the grid there.
      OGRSpatialReference geo;
      geo.CopyGeogCSFrom(&srs);
      geo.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
      std::unique_ptr<OGRCoordinateTransformation> toGeo(OGRCreateCoordinateTransformation(&srs, &geo));
      std::unique_ptr<OGRCoordinateTransformation> toGrid(OGRCreateCoordinateTransformation(&geo, &srs));
      double x = centre[0], y = centre[1];
      if (toGeo && toGrid && toGeo->Transform(1, &x, &y)) {
        f.geographicLocation = true;
        f.centreLon = x;
        f.centreLat = y;
        double nx = x, ny = y + 0.01;
        if (toGrid->Transform(1, &nx, &ny)) {
          f.trueNorthFromY = std::atan2(nx - centre[0], ny - centre[1]) / kDeg;
        }
      }
    }
  }
  f.minHeight = INFINITY;
  f.maxHeight = -INFINITY;
  for (std::size_t i = 0; i < n; ++i) {
    if (f.valid[i]) {
      f.minHeight = std::min(f.minHeight, f.mesh.vertices[i].z());
      f.maxHeight = std::max(f.maxHeight, f.mesh.vertices[i].z());
    }
  }
  if (!(f.minHeight <= f.maxHeight)) f.minHeight = f.maxHeight = 0;
  if (dem.width > 1 && dem.height > 1) {
    // Every vertex has a position (voids are filled), so the centre's neighbours give the size.
    const std::size_t ci = static_cast<std::size_t>(std::floor(cr)) * dem.width +
                           static_cast<std::size_t>(std::floor(cc));
    const auto& v = f.mesh.vertices;
    f.pixelSizeX = (v[ci + 1] - v[ci]).head<2>().norm();
    f.pixelSizeY = (v[ci + dem.width] - v[ci]).head<2>().norm();
  }

  return f;
}

namespace {

// The triangles around vertex (r, c) of localFrame's grid mesh (two per cell, row-major, split
// from the top-left corner), in increasing order: both of the cell up-left, the first of the
// cell up, the second of the cell left, both of its own cell. Returns how many.
int gridRing(const LocalFrame& f, std::size_t i, std::uint32_t ring[6]) {
  const auto w = static_cast<std::size_t>(f.width), h = static_cast<std::size_t>(f.height);
  const std::size_t r = i / w, c = i % w;
  const auto first = [&](std::size_t rr, std::size_t cc) { return static_cast<std::uint32_t>(2 * (rr * (w - 1) + cc)); };
  int n = 0;
  if (r > 0 && c > 0) ring[n++] = first(r - 1, c - 1), ring[n++] = first(r - 1, c - 1) + 1;
  if (r > 0 && c + 1 < w) ring[n++] = first(r - 1, c);
  if (r + 1 < h && c > 0) ring[n++] = first(r, c - 1) + 1;
  if (r + 1 < h && c + 1 < w) ring[n++] = first(r, c), ring[n++] = first(r, c) + 1;
  return n;
}

// Triangles around each vertex, as offsets into one list (a vertex of a DEM has at most 6), for
// a frame whose mesh is not localFrame's grid.
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

// Attached shadow: the light arrives from below the surface at vertex i. Seen from above (the
// frame's z), the light's horizontal direction leaves i through one of its own triangles (exactly:
// the one whose corner sector at i contains that direction); the vertex is in attached shadow when
// the light rises more slowly than that triangle does in that direction. A light straight up, or
// a direction leaving the terrain (across a void or the border), is not attached shadow.
// ring: the triangles around i in increasing order (the first whose sector holds the direction
// decides).
bool attachedShadow(const Mesh& mesh, std::span<const std::uint32_t> ring, std::uint32_t i,
                    const Eigen::Vector3d& light) {
  const Eigen::Vector3d& p = mesh.vertices[i];
  const Point2 p2{p.x(), p.y()}, s2{p.x() + light.x(), p.y() + light.y()};
  if (light.x() == 0 && light.y() == 0) return false;
  for (const std::uint32_t polygon : ring) {
    const auto t = mesh.polygon(polygon);
    // The other two corners, in counter-clockwise order around i.
    std::uint32_t a = t[0] == i ? t[1] : t[1] == i ? t[2] : t[0];
    std::uint32_t b = t[0] == i ? t[2] : t[1] == i ? t[0] : t[1];
    Point2 a2{mesh.vertices[a].x(), mesh.vertices[a].y()}, b2{mesh.vertices[b].x(), mesh.vertices[b].y()};
    const int orientation = orient2dSign(p2, a2, b2);
    if (orientation == 0) continue;
    if (orientation < 0) std::swap(a, b), std::swap(a2, b2);
    if (orient2dSign(p2, a2, s2) < 0 || orient2dSign(p2, s2, b2) < 0) continue;  // not this sector
    // The triangle's rise along the light's horizontal direction, against the light's own rise.
    const Eigen::Vector3d n = (mesh.vertices[a] - p).cross(mesh.vertices[b] - p);  // up-facing
    // On the plane, dz = -(n.x dx + n.y dy) / n.z; below it when light.z < dz.
    return light.z() * n.z() < -(n.x() * light.x() + n.y() * light.y());
  }
  return false;
}

// Candidate occluders for the light rays of a DEM's vertices, found without the light-frame
// quadtree. Seen from above, every ray runs along the sun's azimuth g, at a constant offset c
// across it, rising tan(altitude) per metre of a = position along g. The occluding triangles are
// binned into strips of c (one pixel wide; a triangle goes into every strip its c range meets),
// each strip sorted by the triangles' largest a. A triangle T the ray from P meets, at a point
// ahead of P, has amax(T) >= a(P), and since its highest corner is at least the hit's height,
// zmax(T) - amin(T) tan >= z(P) - a(P) tan: a per-triangle key against a per-point bound. So the
// candidates are the strip's triangles from a(P) on whose key reaches P's bound, found by a
// binary search and a scan that skips blocks of 16 by their largest key (and stops when no later
// block reaches it). Each candidate takes the shadow quadtree's own exact test, and every
// triangle that test can accept is a candidate (the margins are far above the rounding), so the
// mask is the quadtree's.
class HorizonStrips {
 public:
  static constexpr std::uint32_t kNone = 0xffffffffu;

  // occluder: per polygon of the mesh, a number for the occluding triangle (kNone: not one); the
  // entries carry it until renumber.
  HorizonStrips(const Mesh& mesh, const std::vector<std::uint32_t>& occluder, const Eigen::Vector3d& light,
                double stripWidth) {
    const double horizontal = light.head<2>().norm();
    g_ = light.head<2>() / horizontal;
    tan_ = light.z() / horizontal;
    // Margins: a millionth of the coordinates' size, where rounding is below a trillionth.
    double aMax = 0, zMax = 0;
    for (const Eigen::Vector3d& p : mesh.vertices) {
      aMax = std::max(aMax, p.head<2>().norm()), zMax = std::max(zMax, std::fabs(p.z()));
    }
    marginA_ = 1e-6 * (aMax + 1);
    marginKey_ = 1e-6 * (zMax + aMax * tan_ + 1);
    // Each triangle's ranges.
    struct Span {
      double cLo, cHi, aLo, aHi, zHi;
    };
    std::vector<Span> spans;
    std::vector<std::uint32_t> ids;
    spans.reserve(occluder.size());
    ids.reserve(occluder.size());
    cLo_ = INFINITY;
    double cHi = -INFINITY;
    for (std::size_t p = 0; p < occluder.size(); ++p) {
      if (occluder[p] == kNone) continue;
      double cl = INFINITY, ch = -INFINITY, al = INFINITY, ah = -INFINITY, zh = -INFINITY;
      for (std::uint32_t k : mesh.polygon(p)) {
        const Eigen::Vector3d& v = mesh.vertices[k];
        const double a = along(v), c = across(v);
        cl = std::min(cl, c), ch = std::max(ch, c), al = std::min(al, a), ah = std::max(ah, a);
        zh = std::max(zh, v.z());
      }
      // Field by field: a Span built whole was stored in halves and reloaded whole (a stall).
      Span& s = spans.emplace_back();
      s.cLo = cl, s.cHi = ch, s.aLo = al, s.aHi = ah, s.zHi = zh;
      ids.push_back(occluder[p]);
      cLo_ = std::min(cLo_, cl - marginA_), cHi = std::max(cHi, ch + marginA_);
    }
    if (spans.empty()) return;
    width_ = stripWidth;
    const auto strips = static_cast<std::size_t>(std::floor((cHi - cLo_) / width_)) + 1;
    // Each strip's entries padded to whole superblocks (64) with entries no ray reaches.
    std::vector<std::uint64_t> count(strips, 0);
    const auto stripsOf = [&](const Span& s, std::size_t& lo, std::size_t& hi) {
      lo = strip(s.cLo - marginA_), hi = std::min(strips - 1, strip(s.cHi + marginA_));
    };
    for (const Span& s : spans) {
      std::size_t lo, hi;
      stripsOf(s, lo, hi);
      for (std::size_t k = lo; k <= hi; ++k) ++count[k];
    }
    start_.assign(strips + 1, 0);
    for (std::size_t k = 0; k < strips; ++k) start_[k + 1] = start_[k] + (count[k] + kSuper - 1) / kSuper * kSuper;
    entries_.assign(start_[strips], Entry{INFINITY, -INFINITY, INFINITY, -INFINITY, kNone});
    std::vector<std::uint64_t> fill(start_.begin(), start_.end() - 1);
    for (std::size_t t = 0; t < spans.size(); ++t) {
      const Span& s = spans[t];
      std::size_t lo, hi;
      stripsOf(s, lo, hi);
      const Entry e{floatAbove(s.aHi), floatAbove(s.zHi - s.aLo * tan_), floatBelow(s.cLo), floatAbove(s.cHi), ids[t]};
      for (std::size_t k = lo; k <= hi; ++k) entries_[fill[k]++] = e;
    }
    // Each strip by largest a; the largest key of every block (8) and superblock (64), and of
    // every superblock with all after it in the strip.
    blockKey_.assign(entries_.size() / kBlock, -INFINITY);
    superKey_.assign(entries_.size() / kSuper, -INFINITY);
    laterKey_.assign(entries_.size() / kSuper, -INFINITY);
    for (std::size_t k = 0; k < strips; ++k) {
      std::sort(entries_.begin() + static_cast<std::ptrdiff_t>(start_[k]),
                entries_.begin() + static_cast<std::ptrdiff_t>(fill[k]),
                [](const Entry& x, const Entry& y) { return x.aHi < y.aHi; });
      float later = -INFINITY;
      for (std::uint64_t sb = start_[k + 1] / kSuper; sb-- > start_[k] / kSuper;) {
        for (std::uint64_t e = sb * kSuper; e < (sb + 1) * kSuper; ++e) {
          blockKey_[e / kBlock] = std::max(blockKey_[e / kBlock], entries_[e].key);
          superKey_[sb] = std::max(superKey_[sb], entries_[e].key);
        }
        later = std::max(later, superKey_[sb]);
        laterKey_[sb] = later;
      }
    }
  }

  std::size_t stripCount() const { return start_.empty() ? 0 : start_.size() - 1; }
  // The strip of the ray from p; stripCount() when no strip holds it.
  std::size_t stripOf(const Eigen::Vector3d& p) const {
    const double c = across(p);
    if (!(c >= cLo_) || start_.empty()) return stripCount();
    return std::min(strip(c), stripCount());
  }

  // The entries' numbers through `to` (kNone: the entry is no candidate at all).
  void renumber(const std::vector<std::uint32_t>& to) {
    for (Entry& e : entries_) {
      if (e.tri == kNone) continue;
      e.tri = to[e.tri];
      if (e.tri == kNone) e.key = -INFINITY;
    }
  }

  // Whether test(t) holds for a candidate t of the ray from p. hint: where the last search of
  // this thread ended (any value will do; a nearby one is faster).
  template <class Test>
  bool anyAlong(const Eigen::Vector3d& p, std::uint64_t& hint, Test&& test) const {
    const std::size_t k = stripOf(p);
    if (k >= stripCount()) return false;
    const double c = across(p), a = along(p);
    const double bound = p.z() - a * tan_ - marginKey_, aFrom = a - marginA_;
    const double cPlus = c + marginA_, cMinus = c - marginA_;  // against the entries' range
    const Entry* E = entries_.data();
    const std::uint64_t end = start_[k + 1];
    // First entry with aHi >= aFrom: galloping from the hint when it is in this strip (the
    // cells of a strip come nearly in order of a), else a binary search of the strip.
    const auto before = [&](const Entry& x) { return x.aHi < aFrom; };
    std::uint64_t lo = start_[k], hi = end;
    if (hint >= lo && hint < hi) {
      std::uint64_t step = 1;
      if (before(E[hint])) {
        for (lo = hint + 1; lo + step < hi && before(E[lo + step - 1]); step *= 2) lo += step;
        hi = std::min(hi, lo + step);
      } else {
        for (hi = hint; hi > lo + step && !before(E[hi - step]); step *= 2) hi -= step;
        lo = std::max(lo, hi > step ? hi - step : lo);
      }
    }
    std::uint64_t e = static_cast<std::uint64_t>(std::partition_point(E + lo, E + hi, before) - E);
    hint = e;
    if (e >= end || !(laterKey_[e / kSuper] >= bound)) return false;
    for (;;) {
      for (const std::uint64_t blockEnd = (e / kBlock + 1) * kBlock; e < blockEnd; ++e) {
        const Entry& x = E[e];
        if (x.key >= bound && x.cLo <= cPlus && x.cHi >= cMinus && test(x.tri)) return true;
      }
      // At a block boundary: the next block in this superblock that reaches the ray, else the
      // next superblock that does (none: nothing later does).
      while (e % kSuper != 0 && !(blockKey_[e / kBlock] >= bound)) e += kBlock;
      if (e % kSuper != 0) continue;
      if (e >= end || !(laterKey_[e / kSuper] >= bound)) return false;
      while (!(superKey_[e / kSuper] >= bound)) e += kSuper;
      while (!(blockKey_[e / kBlock] >= bound)) e += kBlock;
    }
  }

 private:
  static constexpr std::uint64_t kBlock = 8, kSuper = 64;
  struct Entry {
    float aHi, key, cLo, cHi;  // rounded outward
    std::uint32_t tri;
  };
  double along(const Eigen::Vector3d& v) const { return v.x() * g_.x() + v.y() * g_.y(); }
  double across(const Eigen::Vector3d& v) const { return v.y() * g_.x() - v.x() * g_.y(); }
  std::size_t strip(double c) const { return static_cast<std::size_t>(std::floor((c - cLo_) / width_)); }

  Eigen::Vector2d g_;
  double tan_ = 0, marginA_ = 0, marginKey_ = 0, cLo_ = 0, width_ = 1;
  std::vector<std::uint64_t> start_;
  std::vector<Entry> entries_;
  std::vector<float> blockKey_, superKey_, laterKey_;
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
  const std::size_t n = vertices.size();
  std::vector<Light> out(n, Light::NoData);
  const auto report = [&](double done, const char* message) {
    if (progress && !progress(done, message)) throw Error("shadow computation cancelled");
  };
  if (!towardLight.allFinite() || towardLight.squaredNorm() == 0) {
    throw Error("light direction must be a nonzero finite vector");
  }
  const Eigen::Vector3d light = towardLight.normalized();
  if (light.z() <= 0) {
    // The light is at or below the horizon: no direct light anywhere.
    for (std::size_t i = 0; i < n; ++i) {
      if (frame.valid[i]) out[i] = Light::Shadow;
    }
    report(1.0, "light below the horizon");
    return out;
  }

  // The strips need a horizontal direction to the light (not straight overhead).
  const bool useStrips = search == ShadowSearch::Strips && light.head<2>().norm() > 1e-6;
  const unsigned threads =
      threadCount ? threadCount : std::max(1u, std::min(8u, std::thread::hardware_concurrency()));
  report(0.0, useStrips ? "indexing the occluders" : "building the shadow quadtree");
  // Only triangles facing away from the light can cast a shadow on a cell that is not in attached
  // shadow: its ray starts into the open air, so the first terrain it meets, it enters, and it
  // enters through a triangle whose normal points away from the light. The index therefore
  // holds those alone (and, to stay on the safe side of rounding, those within 1e-9 of edge-on):
  // the same answers as with every triangle, for a fraction of the build.
  Mesh occluders;
  occluders.vertices = frame.mesh.vertices;
  std::vector<std::uint32_t> occluderOf(frame.mesh.polygonCount(), HorizonStrips::kNone);
  for (std::size_t t = 0; t < frame.mesh.polygonCount(); ++t) {
    const auto c = frame.mesh.polygon(t);
    const Eigen::Vector3d& a = frame.mesh.vertices[c[0]];
    const Eigen::Vector3d n = (frame.mesh.vertices[c[1]] - a).cross(frame.mesh.vertices[c[2]] - a);
    // Up-facing normal in the frame (z up); the DEM's corner order may be either way round.
    const Eigen::Vector3d up = n.z() >= 0 ? n : Eigen::Vector3d(-n);
    if (up.dot(light) <= 1e-9 * up.norm()) {
      occluderOf[t] = static_cast<std::uint32_t>(occluders.polygonCount());
      occluders.addTriangle(c[0], c[1], c[2]);
    }
  }
  // The strips (numbered by occluder polygon until the index exists) build on a second core
  // while the index builds on this one.
  std::optional<HorizonStrips> strips;
  const double stripWidth = std::min(frame.pixelSizeX, frame.pixelSizeY);
  const auto buildStrips = [&] { strips.emplace(frame.mesh, occluderOf, light, stripWidth); };
  std::future<void> stripsBuilt;
  if (useStrips && threads > 1) stripsBuilt = std::async(std::launch::async, buildStrips);
  // The light's direction of travel is the "gravity" of the shadow quadtree: "above" a point
  // means toward the light. The strips bring their own candidates and never build the tree.
  TerrainOptions indexOptions = options;
  indexOptions.deferTree = indexOptions.deferTree || useStrips;
  // (On an error here the future's destructor waits for the strips, whose inputs outlive it.)
  const TerrainIndex index(occluders, CartesianMapping(-light), indexOptions);
  const CartesianMapping& mapping = index.mapping();
  // The triangles around each vertex: arithmetic on localFrame's own grid, else a table.
  const bool gridMesh = frame.gridMesh && frame.width > 0 && frame.height > 0 &&
                        frame.mesh.vertices.size() == static_cast<std::size_t>(frame.width) * frame.height &&
                        frame.mesh.polygonCount() == 2 * static_cast<std::size_t>(frame.width - 1) * (frame.height - 1);
  std::optional<VertexStar> star;
  if (!gridMesh) star.emplace(frame.mesh);
  if (useStrips) {
    if (stripsBuilt.valid()) {
      stripsBuilt.get();  // rethrows the side thread's error
    } else {
      buildStrips();
    }
    const TerrainIndex::PolygonTriangles of = index.trianglesOfPolygons();
    std::vector<std::uint32_t> triangleOf(occluders.polygonCount(), HorizonStrips::kNone);
    for (std::size_t o = 0; o < triangleOf.size(); ++o) {
      // A triangle seen edge-on along the light has no triangle in the index (a wall).
      if (of.start[o + 1] > of.start[o]) triangleOf[o] = of.tris[of.start[o]];
    }
    strips->renumber(triangleOf);
  }
  report(0.3, "testing cells");

  // Two passes over the cells, each shared out to the machine's cores in groups (the calling
  // thread reports progress): attached shadow by rows, reading each vertex's ring in memory
  // order; then cast shadow for the cells still lit, by rows through the quadtree or by strips
  // through the strips (each strip's cells in row order, so nearly in order of a: consecutive
  // searches read the same few cache lines of the same strip).
  const std::size_t cellCount = vertices.size();
  const auto width = static_cast<std::size_t>(frame.width);
  std::atomic<std::size_t> cellsDone{0};
  std::atomic<bool> stop{false};
  const auto inParallel = [&](std::size_t groups, const auto& cellsOf, const auto& body) {
    std::atomic<std::size_t> next{0};
    const auto work = [&](bool reporter) {
      for (std::size_t g; !stop && (g = next++) < groups;) {
        body(g);
        const std::size_t done = cellsDone += cellsOf(g);
        const double fraction = static_cast<double>(done) / static_cast<double>(2 * std::max<std::size_t>(1, cellCount));
        if (reporter && progress && !progress(0.3 + 0.7 * fraction, "testing cells")) stop = true;
      }
    };
    std::vector<std::thread> pool;
    for (unsigned t = 1; t < threads; ++t) pool.emplace_back(work, false);
    work(true);
    for (auto& t : pool) t.join();
  };
  const auto rowCells = [&](std::size_t) { return width; };
  inParallel(static_cast<std::size_t>(frame.height), rowCells, [&](std::size_t r) {
    for (std::size_t i = r * width; i < (r + 1) * width; ++i) {
      if (!frame.valid[i]) continue;
      std::uint32_t grid[6];
      const std::span<const std::uint32_t> ring =
          gridMesh ? std::span<const std::uint32_t>(grid, static_cast<std::size_t>(gridRing(frame, i, grid)))
                   : std::span<const std::uint32_t>(star->tris.data() + star->start[i], star->start[i + 1] - star->start[i]);
      out[i] = attachedShadow(frame.mesh, ring, static_cast<std::uint32_t>(i), light) ? Light::Shadow : Light::Lit;
    }
  });
  const auto castShadow = [&](std::size_t i, std::uint64_t& hint) {
    if (out[i] != Light::Lit) return;
    const auto vi = static_cast<std::uint32_t>(i);
    const Eigen::Vector3d m = mapping.toMapped(vertices[i]);
    const auto occludes = [&](std::uint32_t t) { return index.triangleOccludesAbove(t, m.x(), m.y(), m.z(), vi); };
    if (strips ? strips->anyAlong(vertices[i], hint, occludes) : index.occludedAbove(m.x(), m.y(), m.z(), vi)) {
      out[i] = Light::Shadow;
    }
  };
  if (strips) {
    std::vector<std::uint32_t> stripOf(cellCount), order(cellCount);
    std::vector<std::uint64_t> start(strips->stripCount() + 2, 0);  // the last: cells in none
    for (std::size_t i = 0; i < cellCount; ++i) {
      stripOf[i] = static_cast<std::uint32_t>(strips->stripOf(vertices[i]));
      ++start[stripOf[i] + 1];
    }
    for (std::size_t g = 1; g < start.size(); ++g) start[g] += start[g - 1];
    std::vector<std::uint64_t> fill(start.begin(), start.end() - 1);
    for (std::size_t i = 0; i < cellCount; ++i) order[fill[stripOf[i]]++] = static_cast<std::uint32_t>(i);
    inParallel(start.size() - 1, [&](std::size_t g) { return start[g + 1] - start[g]; }, [&](std::size_t g) {
      std::uint64_t hint = 0;
      for (std::uint64_t k = start[g]; k < start[g + 1]; ++k) castShadow(order[k], hint);
    });
  } else {
    inParallel(static_cast<std::size_t>(frame.height), rowCells, [&](std::size_t r) {
      std::uint64_t hint = 0;
      for (std::size_t i = r * width; i < (r + 1) * width; ++i) castShadow(i, hint);
    });
  }
  if (stop) throw Error("shadow computation cancelled");
  report(1.0, "done");
  return out;
}

}  // namespace qota
