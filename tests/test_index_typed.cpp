// Every index, one suite: the face of index.hpp (point, world, cursor, batch and line queries,
// statistics, the no-terrain policy) run over each index type against a brute force that shares
// none of the quadtree's code.
//
// A type is a fixture traits struct: its index and mapping, a random terrain for that mapping,
// its index options, and which half of the mapping's line carries its (u, v). Queries are drawn
// from the mapping's own domain (a periodic u, a latitude, unbounded axes), so a new mapping
// (an east-north-up plane, say) is one more struct and one more line in AllIndexes.
//
// The oracle: the mapping's world line (mapping.line(u, v): origin + t down,
// coords/qota/mapping.hpp) against every polygon of the mesh in long double: the crossing of the
// plane of the polygon's fan triangle the line passes deepest inside (the fan the indexes make,
// from the first corner), and how far inside the polygon's outline the line passes (the
// smallest signed distance to an outline edge, measured across the line). A crossing farther
// inside than `ambiguous` is sure, one within `ambiguous` of the outline may go either way: the
// index may report it or not (a point on a shared edge, a vertex, a seam). Heights closer than
// the tolerance to each other or to the query height make the choice between them open as well.
// Everything else must be the oracle's answer exactly (polygon) and to the tolerance (height,
// point, normal). Where two polygons share an edge from opposite sides, or the surface is
// closed, the watertight rule holds as well: something is hit.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <iomanip>
#include <limits>
#include <map>
#include <memory>
#include <numeric>
#include <optional>
#include <ostream>
#include <random>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "qota/curved.hpp"
#include "qota/error.hpp"
#include "qota/index.hpp"
#include "qota/synthetic.hpp"
#include "qota/terrain.hpp"
#include "random_globe.hpp"
#include "random_terrain.hpp"

namespace {

using namespace qota;
using Real = long double;
using Vec3L = Eigen::Matrix<Real, 3, 1>;
constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

double uniform(std::mt19937_64& rng, double lo, double hi) {
  return std::uniform_real_distribution<double>(lo, hi)(rng);
}

// Convex plates for the curved terrains: n corners at sorted random angles on a circle of
// `radius` around `centre`, in the plane perpendicular to `normal`, either winding.
void addPlate(Mesh& m, const Eigen::Vector3d& centre, const Eigen::Vector3d& normal, double radius,
              std::mt19937_64& rng) {
  const int n = 3 + static_cast<int>(uniform(rng, 0, 4));
  const Eigen::Vector3d e1 = normal.unitOrthogonal(), e2 = normal.normalized().cross(e1);
  std::vector<double> angle(n);
  for (double& a : angle) a = uniform(rng, 0, 2 * M_PI);
  std::sort(angle.begin(), angle.end());
  std::vector<std::uint32_t> corners;
  for (double a : angle) corners.push_back(m.addVertex(centre + radius * (std::cos(a) * e1 + std::sin(a) * e2)));
  if (uniform(rng, 0, 1) < 0.5) std::reverse(corners.begin(), corners.end());
  m.addPolygon(corners);
}

// ---------------------------------------------------------------------------------------------
// Fixture traits: one struct per index type.
//
//   kName, Index, Mapping   the type's name in test names, the index and its mapping
//   kParallelLines          the mapping's lines are parallel (a polygon seen edge-on is a wall,
//                           left out); else a zero-area triangle is what is left out
//   kClosed                 the terrain is closed around the mapping's lines: every valid (u, v)
//                           inside the mesh's v range must hit
//   kGridFastPath           the index answers from the regular-grid fast path
//   mesh(), mapping(), options()
//   onLine(mapping, v, h)   whether the point of height h on the line of (u, v) is on the part
//                           of the line that belongs to (u, v) (a ray from a centre or an axis)
//   singular(mapping)       world points the mapping cannot map (no terrain there, no error)

struct Planar {
  using Index = CartesianIndex;
  using Mapping = CartesianMapping;
  static constexpr bool kParallelLines = true;
  static constexpr bool kClosed = false;
  static constexpr bool kGridFastPath = false;
  static IndexOptions options() { return {.tree = {}, .gridFastPath = false}; }
  static bool onLine(const Mapping&, double, double) { return true; }
  static std::vector<Eigen::Vector3d> singular(const Mapping&) { return {}; }
};

// A heightfield with holes, floating plates of 3 to 7 corners (overlaps, overhangs) and walls.
struct CartesianVertical : Planar {
  static constexpr const char* kName = "CartesianVertical";
  static Mesh mesh() { return test::randomTerrain({}, 101); }
  static Mapping mapping() { return CartesianMapping(); }
};

// The same kind of terrain under a tilted gravity (the walls are then seen, not left out).
struct CartesianTilted : Planar {
  static constexpr const char* kName = "CartesianTilted";
  static Mesh mesh() { return test::randomTerrain({}, 102); }
  static Mapping mapping() { return CartesianMapping({0.3, -0.2, -1}, {3, 4, 5}); }
  static IndexOptions options() { return {}; }  // the fast path where it applies: here nowhere
};

// A raster-like grid: heights exact in float (an Int16 or Float32 raster), nodata holes, the
// fast path asked for.
struct CartesianGrid : Planar {
  static constexpr const char* kName = "CartesianGrid";
  static constexpr bool kGridFastPath = true;
  static Mesh mesh() {
    Heightfield f = fractalHeightfield(64, 48, 0.5, 6.0, 103);
    f.x0 = -7, f.y0 = 3;
    for (double& z : f.z) z = static_cast<float>(z);
    const Mesh full = f.toMesh();
    Mesh m;
    m.vertices = full.vertices;
    std::mt19937_64 rng(104);
    for (std::size_t p = 0; p < full.polygonCount(); ++p) {
      if (uniform(rng, 0, 1) >= 0.05) m.addPolygon(full.polygon(p));
    }
    return m;
  }
  static Mapping mapping() { return CartesianMapping(); }
  static IndexOptions options() { return {.tree = {}, .gridFastPath = true}; }
};

// A grid rotated about the vertical (still an affine grid), in map coordinates in the millions
// with the mapping's origin near the data.
struct CartesianRotatedGrid : Planar {
  static constexpr const char* kName = "CartesianRotatedGrid";
  static constexpr bool kGridFastPath = true;
  static Mesh mesh() {
    Mesh m = fractalHeightfield(48, 40, 2.5, 30.0, 105).toMesh();
    const Eigen::Matrix3d r = Eigen::AngleAxisd(0.52, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    for (auto& p : m.vertices) p = r * p + Eigen::Vector3d(3e5, 5e6, 0);
    return m;
  }
  static Mapping mapping() { return CartesianMapping({0, 0, -1}, {3e5, 5e6, 0}); }
  static IndexOptions options() { return {.tree = {}, .gridFastPath = true}; }
};

// Earth-centred (ECEF) data in a local east-north-up frame: the heightfield of the first type
// (without walls) placed around a point on the flank of Mount Rainier, every vertex in ECEF metres.
struct Enu : Planar {
  using Index = EnuIndex;
  using Mapping = EnuMapping;
  static constexpr const char* kName = "Enu";
  static Mesh mesh() {
    // No walls: a wall vertical in the ENU frame is, after the rounding of its ECEF corners, a
    // sliver seen nearly edge-on, whose crossing height no two roundings agree on.
    Mesh m = test::randomTerrain({.walls = 0}, 106);
    const Mapping enu = mapping();
    for (auto& p : m.vertices) p = enu.toWorld(100.0 * p);
    return m;
  }
  static Mapping mapping() { return EnuMapping(46.85, -121.76, 1500.0); }
  static bool onLine(const Mapping&, double, double) { return true; }
  static std::vector<Eigen::Vector3d> singular(const Mapping&) { return {}; }
};

template <class M>
struct Axial {
  using Index = CurvedIndex<M>;
  using Mapping = M;
  static constexpr bool kParallelLines = false;
  static constexpr bool kClosed = true;
  static constexpr bool kGridFastPath = false;
  static IndexOptions options() { return {}; }
  static std::vector<Eigen::Vector3d> singular(const Mapping&) { return {}; }
};

// A bumpy planet off the origin with a vertex exactly on each pole (pole fans), and plates
// inside it (a layer under the surface), one across the seam and one over the north pole.
struct Spherical : Axial<SphericalMapping> {
  static constexpr const char* kName = "Spherical";
  static Eigen::Vector3d centre() { return {1e3, -2e3, 5e2}; }
  static Mesh mesh() {
    std::mt19937_64 rng(201);
    Mesh m = test::unitIcosphere(4, rng, false);
    for (auto& p : m.vertices) p = centre() + 1000.0 * (1 + 0.02 * uniform(rng, -1, 1)) * p;
    std::normal_distribution<double> g;
    for (int i = 0; i < 40; ++i) {
      Eigen::Vector3d dir = Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized();
      if (i == 0) dir = {-1, 0, 0.1};
      if (i == 1) dir = {0, 0, 1};
      addPlate(m, centre() + 800.0 * dir.normalized(), dir, uniform(rng, 30, 120), rng);
    }
    return m;
  }
  static Mapping mapping() { return SphericalMapping(centre()); }
  static bool onLine(const Mapping&, double, double h) { return h > 0; }  // the ray from the centre
  static std::vector<Eigen::Vector3d> singular(const Mapping& m) { return {m.centre()}; }
};

// The WGS84 ellipsoid with relief, its poles inside triangles (a randomly rotated icosphere),
// and plates 20 km down.
struct Geodetic : Axial<GeodeticMapping> {
  static constexpr const char* kName = "Geodetic";
  static Mesh mesh() {
    std::mt19937_64 rng(301);
    const GeodeticMapping wgs;
    Mesh m = test::unitIcosphere(4, rng, true);
    for (auto& p : m.vertices) {
      const double lon = longitudeOf(p.x(), p.y());
      const double lat = std::atan2(p.z(), std::hypot(p.x(), p.y())) * 180 / M_PI;
      p = wgs.toWorld({lon, lat, uniform(rng, -500, 9000)});
    }
    for (int i = 0; i < 40; ++i) {
      double lon = uniform(rng, -180, 180), lat = std::asin(uniform(rng, -1, 1)) * 180 / M_PI;
      if (i == 0) lon = 180, lat = 20;
      if (i == 1) lat = -90;
      addPlate(m, wgs.toWorld({lon, lat, -20000}), GeodeticMapping::up(lon, lat), uniform(rng, 5e4, 2e5), rng);
    }
    return m;
  }
  static Mapping mapping() { return GeodeticMapping(); }
  // The normal of latitude v crosses the axis N (v) below the surface: the far side is another line.
  static bool onLine(const Mapping& m, double v, double h) { return h + m.primeVerticalRadius(v) > 0; }
};

// A station around a tilted, offset axis: a bumpy tube, open at both ends, with plates nearer
// the axis (a ceiling over part of the floor).
struct Cylindrical : Axial<CylindricalMapping> {
  static constexpr const char* kName = "Cylindrical";
  static Eigen::Vector3d point() { return {10, -20, 30}; }
  static Eigen::Vector3d axis() { return Eigen::Vector3d(0.3, -0.2, 1).normalized(); }
  static Mesh mesh() {
    std::mt19937_64 rng(401);
    Mesh m = test::bumpyTube(96, 33, 250.0, 1000.0, 0.03, rng);
    for (int i = 0; i < 40; ++i) {
      const double a = i == 0 ? M_PI : uniform(rng, -M_PI, M_PI), z = uniform(rng, -450, 450);
      const Eigen::Vector3d out(std::cos(a), std::sin(a), 0);
      addPlate(m, 200.0 * out + Eigen::Vector3d(0, 0, z), out, uniform(rng, 10, 40), rng);
    }
    const Eigen::Quaterniond q = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d(0, 0, 1), axis());
    for (auto& p : m.vertices) p = q * p + point();
    return m;
  }
  static Mapping mapping() { return CylindricalMapping(point(), axis()); }
  static bool onLine(const Mapping&, double, double h) { return h > 0; }  // the ray from the axis
  static std::vector<Eigen::Vector3d> singular(const Mapping& m) {
    return {m.axisPoint(), m.axisPoint() + 123.0 * m.axisDirection()};
  }
};

using AllIndexes = ::testing::Types<CartesianVertical, CartesianTilted, CartesianGrid, CartesianRotatedGrid, Enu,
                                    Spherical, Geodetic, Cylindrical>;

struct TraitsName {
  template <class T>
  static std::string GetName(int) {
    return T::kName;
  }
};

// ---------------------------------------------------------------------------------------------
// The oracle.

// A line's crossing of one polygon's plane (or of one fan triangle's).
struct Crossing {
  std::uint32_t polygon = 0;
  Real t = 0;              // along the line's direction
  double margin = 0;       // how far inside the outline: > 0 inside, < 0 outside (a length)
  Eigen::Vector3d normal;  // unit normal of the plane, either side
};

class Oracle {
 public:
  Oracle(const Mesh& mesh, double ambiguous) : ambiguous_(ambiguous) {
    for (std::size_t p = 0; p < mesh.polygonCount(); ++p) {
      const auto idx = mesh.polygon(p);
      if (idx.size() > kMaxCorners) throw Error("the oracle takes polygons of up to 16 corners");
      Polygon poly{static_cast<std::uint32_t>(corners_.size()), static_cast<std::uint32_t>(idx.size()),
                   Eigen::Vector3d::Zero(), 0};
      for (std::uint32_t i : idx) {
        corners_.push_back(mesh.vertices[i].cast<Real>());
        poly.centre += mesh.vertices[i] / static_cast<double>(idx.size());
      }
      for (std::uint32_t i : idx) poly.radius = std::max(poly.radius, (mesh.vertices[i] - poly.centre).norm());
      poly.radius = poly.radius * (1 + 1e-9) + ambiguous;
      polygons_.push_back(poly);
    }
  }

  std::size_t polygonCount() const { return polygons_.size(); }
  std::span<const Vec3L> corners(std::size_t p) const {
    return {corners_.data() + polygons_[p].first, polygons_[p].count};
  }

  // Every polygon whose plane the line o + t d (d unit, t any real) crosses inside its outline
  // or within `ambiguous` of it.
  std::vector<Crossing> polygons(const Eigen::Vector3d& o, const Eigen::Vector3d& d) const {
    std::vector<Crossing> out;
    const Vec3L ol = o.cast<Real>(), dl = d.cast<Real>();
    for (std::uint32_t p = 0; p < polygons_.size(); ++p) {
      if (far(p, o, d)) continue;
      if (auto c = cross(corners(p), ol, dl)) {
        c->polygon = p;
        out.push_back(*c);
      }
    }
    return out;
  }

  // The same per fan triangle (corners 0, k, k + 1), for polygons and triangles `keep` keeps.
  template <class Keep>
  std::vector<Crossing> triangles(const Eigen::Vector3d& o, const Eigen::Vector3d& d, Keep&& keep) const {
    std::vector<Crossing> out;
    const Vec3L ol = o.cast<Real>(), dl = d.cast<Real>();
    for (std::uint32_t p = 0; p < polygons_.size(); ++p) {
      if (far(p, o, d)) continue;
      const auto c = corners(p);
      for (std::size_t k = 1; k + 1 < c.size(); ++k) {
        const std::array<Vec3L, 3> tri{c[0], c[k], c[k + 1]};
        if (!keep(p, std::span<const Vec3L>(tri))) continue;
        if (auto x = cross(tri, ol, dl)) {
          x->polygon = p;
          out.push_back(*x);
        }
      }
    }
    return out;
  }

  // Twice the area of polygon c seen along d (0: seen edge-on).
  static Real projectedArea(std::span<const Vec3L> c, const Vec3L& d) {
    Real area = 0;
    for (std::size_t k = 1; k + 1 < c.size(); ++k) area += (c[k] - c[0]).cross(c[k + 1] - c[0]).dot(d);
    return area;
  }

 private:
  static constexpr std::size_t kMaxCorners = 16;
  struct Polygon {
    std::uint32_t first, count;
    Eigen::Vector3d centre;  // a bounding sphere, for a quick rejection
    double radius;
  };

  // Whether the line passes clear of polygon p's bounding sphere (then more than `ambiguous`
  // outside the polygon).
  bool far(std::uint32_t p, const Eigen::Vector3d& o, const Eigen::Vector3d& d) const {
    const Polygon& poly = polygons_[p];
    return (poly.centre - o).cross(d).squaredNorm() > poly.radius * poly.radius;
  }

  std::optional<Crossing> cross(std::span<const Vec3L> c, const Vec3L& o, const Vec3L& d) const {
    const std::size_t n = c.size();
    std::array<Vec3L, kMaxCorners> q;
    for (std::size_t k = 0; k < n; ++k) q[k] = c[k] - o;
    // side(i, j): twice the signed area of (line, c_i, c_j) seen along d; over the length of the
    // edge seen along d, the signed distance of the line from the edge.
    auto side = [&](std::size_t i, std::size_t j) { return q[i].cross(q[j]).dot(d); };
    auto distance = [&](std::size_t i, std::size_t j, Real sign) {
      const Real length = (c[j] - c[i]).cross(d).norm();
      return length > 0 ? sign * side(i, j) / length : std::numeric_limits<Real>::infinity();
    };
    Real area = 0;
    for (std::size_t k = 0; k < n; ++k) area += side(k, (k + 1) % n);
    if (area == 0) return std::nullopt;  // seen edge-on
    const Real sign = area > 0 ? 1 : -1;
    Real margin = std::numeric_limits<Real>::infinity();
    for (std::size_t k = 0; k < n; ++k) margin = std::min(margin, distance(k, (k + 1) % n, sign));
    if (margin < -ambiguous_) return std::nullopt;
    // The plane of the fan triangle the line passes deepest inside.
    std::size_t best = 1;
    Real bestDepth = -std::numeric_limits<Real>::infinity();
    for (std::size_t k = 1; n > 3 && k + 1 < n; ++k) {
      const Real depth = std::min({distance(0, k, sign), distance(k, k + 1, sign), distance(k + 1, 0, sign)});
      if (depth > bestDepth) best = k, bestDepth = depth;
    }
    const Vec3L normal = (q[best] - q[0]).cross(q[best + 1] - q[0]);
    const Real nd = normal.dot(d);
    if (nd == 0) return std::nullopt;
    Crossing x;
    x.t = normal.dot(q[0]) / nd;
    x.margin = static_cast<double>(margin);
    x.normal = normal.normalized().template cast<double>();
    return x;
  }

  std::vector<Vec3L> corners_;
  std::vector<Polygon> polygons_;
  double ambiguous_;
};

// ---------------------------------------------------------------------------------------------
// One type's terrain, index and oracle, built once for its tests.

template <class T>
struct World {
  using Index = typename T::Index;
  static_assert(TerrainQuery<Index>);
  static_assert(EditableTerrain<Index>);

  Mesh mesh = T::mesh();
  typename T::Mapping mapping = T::mapping();
  Index index{mesh, mapping, T::options()};
  double scale = scaleOf(mesh);  // bounds the world coordinates
  // The bound index.hpp states: nearer an outline than this, either answer; heights, points
  // and line parameters within it.
  double ambiguous = qota::kAnswerAccuracy * scale;
  double tolerance = qota::kAnswerAccuracy * scale;
  Oracle oracle{mesh, ambiguous};
  MappedDomain domain = mapping.domain();
  Box2 box;                           // the mapped vertices' (u, v)
  double hlo = kInf, hhi = -kInf;     // and h
  std::vector<std::uint8_t> leftOut;  // per polygon, as the index must leave it out
  std::uint64_t expectTriangles = 0, expectLeftOut = 0;

  World() {
    box = {kInf, kInf, -kInf, -kInf};
    for (const auto& p : mesh.vertices) {
      const Eigen::Vector3d m = mapping.toMapped(p);
      box.ulo = std::min(box.ulo, m.x()), box.uhi = std::max(box.uhi, m.x());
      box.vlo = std::min(box.vlo, m.y()), box.vhi = std::max(box.vhi, m.y());
      hlo = std::min(hlo, m.z()), hhi = std::max(hhi, m.z());
    }
    // Parallel lines leave out the polygons seen edge-on (walls); curved ones the triangles of
    // no area.
    const Vec3L down = mapping.line(0, 0).down.template cast<Real>();
    leftOut.assign(oracle.polygonCount(), 0);
    for (std::size_t p = 0; p < oracle.polygonCount(); ++p) {
      const auto c = oracle.corners(p);
      if constexpr (T::kParallelLines) {
        if (Oracle::projectedArea(c, down) == 0) {
          leftOut[p] = 1, ++expectLeftOut;
          continue;
        }
      }
      for (std::size_t k = 1; k + 1 < c.size(); ++k) {
        const std::array<Vec3L, 3> tri{c[0], c[k], c[k + 1]};
        if (keepTriangle(p, tri)) {
          ++expectTriangles;
        } else if (!T::kParallelLines) {
          ++expectLeftOut;
        }
      }
    }
  }

  static double scaleOf(const Mesh& m) {
    double s = 0;
    for (const auto& p : m.vertices) s = std::max(s, p.norm());
    return s;
  }

  // Whether the index keeps fan triangle tri of polygon p (alongLine meets only those).
  bool keepTriangle(std::uint32_t p, std::span<const Vec3L> tri) const {
    if constexpr (T::kParallelLines) {
      const Vec3L down = mapping.line(0, 0).down.template cast<Real>();
      return !leftOut[p] && (oracle.corners(p).size() == 3 || Oracle::projectedArea(tri, down) != 0);
    } else {
      return (tri[1] - tri[0]).cross(tri[2] - tri[0]).squaredNorm() != 0;
    }
  }

  double elevation(double h) const { return T::Mapping::kHeightUp ? h : -h; }
  double fromElevation(double e) const { return T::Mapping::kHeightUp ? e : -e; }
  bool latitudes() const { return std::isfinite(domain.vlo); }  // v ends in poles

  // A random (u, v): u over the mapping's period (sometimes some periods away, which names the
  // same line) or the terrain's extent and a little beyond; v uniform over a sphere's area
  // between poles, or over the terrain's extent.
  Point2 drawUV(std::mt19937_64& rng) const {
    Point2 p;
    if (domain.periodicU) {
      p.u = uniform(rng, domain.ulo, domain.uhi);
      if (rng() % 8 == 0) p.u += (domain.uhi - domain.ulo) * static_cast<double>(static_cast<int>(rng() % 5) - 2);
    } else {
      const double pad = 0.05 * (box.uhi - box.ulo);
      p.u = uniform(rng, box.ulo - pad, box.uhi + pad);
    }
    if (latitudes()) {
      p.v = domain.vlo + (domain.vhi - domain.vlo) * (std::asin(uniform(rng, -1, 1)) / M_PI + 0.5);
    } else {
      const double pad = 0.05 * (box.vhi - box.vlo);
      p.v = uniform(rng, box.vlo - pad, box.vhi + pad);
    }
    return p;
  }
  double drawH(std::mt19937_64& rng) const {
    const double pad = 0.05 * (hhi - hlo);
    return uniform(rng, hlo - pad, hhi + pad);
  }
  // Whether the watertight rule makes (u, v) hit: a closed terrain, inside its v range (an open
  // tube's rims may round outside).
  bool mustHit(double u, double v) const {
    if (!T::kClosed || !std::isfinite(u) || !std::isfinite(v)) return false;
    if (latitudes()) return v >= domain.vlo && v <= domain.vhi;
    const double rim = 1e-6 * (box.vhi - box.vlo);
    return v >= box.vlo + rim && v <= box.vhi - rim;
  }
};

// ---------------------------------------------------------------------------------------------
// Comparisons.

struct At {
  double u, v, h;
};
std::ostream& operator<<(std::ostream& os, const At& q) {
  return os << std::setprecision(17) << " at (u, v, h) = (" << q.u << ", " << q.v << ", " << q.h << ")";
}

bool sameBits(double a, double b) { return std::bit_cast<std::uint64_t>(a) == std::bit_cast<std::uint64_t>(b); }
bool sameBits(const std::optional<double>& a, const std::optional<double>& b) {
  return a.has_value() == b.has_value() && (!a || sameBits(*a, *b));
}
// The same hit: polygon and height bit for bit, point and normal equal (a zero's sign aside).
bool sameHit(const Hit& a, const Hit& b) {
  return a.polygon == b.polygon && sameBits(a.height, b.height) && a.world == b.world && a.normal == b.normal;
}
bool sameHit(const std::optional<Hit>& a, const std::optional<Hit>& b) {
  return a.has_value() == b.has_value() && (!a || sameHit(*a, *b));
}
bool sameHits(const std::vector<Hit>& a, const std::vector<Hit>& b) {
  return a.size() == b.size() &&
         std::equal(a.begin(), a.end(), b.begin(), [](const Hit& x, const Hit& y) { return sameHit(x, y); });
}

// The oracle's crossings of the line of (u, v), on the part of it that is (u, v)'s.
struct LineCrossing {
  std::uint32_t polygon;
  double h;
  bool sure;           // well inside the outline
  Eigen::Vector3d up;  // the plane's unit normal, against down
};

template <class T>
std::vector<LineCrossing> oracleAt(const World<T>& w, double u, double v) {
  const MappedLine line = w.mapping.line(u, v);
  std::vector<LineCrossing> out;
  for (const Crossing& c : w.oracle.polygons(line.origin, line.down)) {
    // h grows against down when kHeightUp, along it otherwise; the origin has h = 0.
    const double h = static_cast<double>(T::Mapping::kHeightUp ? -c.t : c.t);
    if (!T::onLine(w.mapping, v, h)) continue;
    out.push_back(
        {c.polygon, h, c.margin > w.ambiguous, c.normal.dot(line.down) > 0 ? Eigen::Vector3d(-c.normal) : c.normal});
  }
  return out;
}

// Whether the oracle's answer at (u, v) is open: a crossing near an outline, or two polygons
// at heights within the tolerance.
template <class T>
bool openChoice(const World<T>& w, const std::vector<LineCrossing>& xs) {
  for (std::size_t i = 0; i < xs.size(); ++i) {
    if (!xs[i].sure) return true;
    for (std::size_t j = 0; j < i; ++j) {
      if (std::fabs(xs[i].h - xs[j].h) <= w.tolerance) return true;
    }
  }
  return false;
}

// A hit's point is the line's at its height, its normal the polygon's, pointing up.
template <class T>
void checkGeometry(const World<T>& w, const Hit& got, const LineCrossing& x, double u, double v, const At& at,
                   const char* what) {
  const Eigen::Vector3d expect = w.mapping.toWorld({u, v, got.height});
  ASSERT_LE((got.world - expect).norm(), w.tolerance) << what << ": point off the line" << at;
  ASSERT_NEAR(got.normal.norm(), 1.0, 1e-12) << what << at;
  const Eigen::Vector3d down = w.mapping.line(u, v).down;
  if (std::fabs(x.up.dot(down)) > 1e-6) {
    ASSERT_LE((got.normal - x.up).norm(), 1e-6)
        << what << ": normal " << got.normal.transpose() << ", want " << x.up.transpose() << at;
  }
}

// The nearest hit at or below (or above) elevation ez, against the oracle: the polygon must be
// on the line at the oracle's height, on the query's side, with no crossing sure to be nearer;
// none only when no crossing is sure to be on that side. When nothing is open, exactly the
// oracle's polygon.
template <class T>
void checkNearest(const World<T>& w, const char* what, const std::optional<Hit>& got, bool below, double ez,
                  const std::vector<LineCrossing>& xs, double u, double v, const At& at, bool open) {
  const double tol = w.tolerance;
  const LineCrossing* want = nullptr;
  for (const LineCrossing& x : xs) {
    const double e = w.elevation(x.h);
    if (std::fabs(e - ez) <= tol) open = true;
    // A crossing at the query height to rounding may fall on either side: never a must.
    if (!x.sure || std::fabs(e - ez) <= tol || (below ? e > ez : e < ez)) continue;
    if (!want || (below ? e > w.elevation(want->h) : e < w.elevation(want->h))) want = &x;
  }
  if (got) {
    const auto x = std::find_if(xs.begin(), xs.end(), [&](const LineCrossing& c) { return c.polygon == got->polygon; });
    ASSERT_NE(x, xs.end()) << what << ": polygon " << got->polygon << " is not on the line" << at;
    ASSERT_NEAR(got->height, x->h, tol) << what << ": polygon " << got->polygon << at;
    const double e = w.elevation(got->height);
    ASSERT_TRUE(below ? e <= ez : e >= ez) << what << ": height " << got->height << " on the wrong side" << at;
    if (want) {
      const double ew = w.elevation(want->h);
      ASSERT_FALSE(below ? ew > e + tol : ew < e - tol)
          << what << ": polygon " << got->polygon << " at " << got->height << ", but polygon " << want->polygon
          << " at " << want->h << " is nearer" << at;
    }
    checkGeometry(w, *got, *x, u, v, at, what);
  } else {
    ASSERT_TRUE(!want || std::fabs(w.elevation(want->h) - ez) <= tol)
        << what << ": nothing, but polygon " << want->polygon << " at " << want->h << at;
  }
  if (!open) {
    ASSERT_EQ(got.has_value(), want != nullptr) << what << at;
    if (got) {
      ASSERT_EQ(got->polygon, want->polygon) << what << at;
    }
  }
}

// Every hit: each polygon on the line once, top first, every sure crossing among them.
template <class T>
void checkAll(const World<T>& w, const char* what, const std::vector<Hit>& got, const std::vector<LineCrossing>& xs,
              double u, double v, const At& at, bool open) {
  for (std::size_t i = 0; i < got.size(); ++i) {
    const auto x =
        std::find_if(xs.begin(), xs.end(), [&](const LineCrossing& c) { return c.polygon == got[i].polygon; });
    ASSERT_NE(x, xs.end()) << what << ": polygon " << got[i].polygon << " is not on the line" << at;
    ASSERT_NEAR(got[i].height, x->h, w.tolerance) << what << ": polygon " << got[i].polygon << at;
    checkGeometry(w, got[i], *x, u, v, at, what);
    for (std::size_t j = 0; j < i; ++j) {
      ASSERT_NE(got[j].polygon, got[i].polygon) << what << ": polygon " << got[i].polygon << " twice" << at;
    }
    if (i > 0) {
      const double e0 = w.elevation(got[i - 1].height), e1 = w.elevation(got[i].height);
      ASSERT_TRUE(e0 > e1 || (e0 == e1 && got[i - 1].polygon < got[i].polygon)) << what << ": not top first" << at;
    }
  }
  std::size_t sure = 0;
  for (const LineCrossing& x : xs) {
    if (!x.sure) continue;
    ++sure;
    ASSERT_TRUE(std::any_of(got.begin(), got.end(), [&](const Hit& g) { return g.polygon == x.polygon; }))
        << what << ": polygon " << x.polygon << " at " << x.h << " missing" << at;
  }
  if (!open) {
    ASSERT_EQ(got.size(), sure) << what << at;
  }
}

struct Counts {
  int queries = 0, clear = 0, mustHit = 0;
};

// Every point query at (u, v, h), and (withWorld) every world query at the world point of
// (u, v, h), against the oracle and against each other.
template <class T>
void checkPoint(const World<T>& w, double u, double v, double h, bool mustHit, bool withWorld, Counts& n) {
  const auto& index = w.index;
  const At at{u, v, h};
  const std::vector<LineCrossing> xs = oracleAt(w, u, v);
  const bool open = openChoice(w, xs);
  const double ez = w.elevation(h);
  ++n.queries;
  n.clear += !open;
  n.mustHit += mustHit;

  const auto top = index.top(u, v), below = index.below(u, v, h), above = index.above(u, v, h);
  checkNearest(w, "top", top, true, kInf, xs, u, v, at, open);
  checkNearest(w, "below", below, true, ez, xs, u, v, at, open);
  checkNearest(w, "above", above, false, ez, xs, u, v, at, open);
  if (::testing::Test::HasFatalFailure()) return;
  if (mustHit) {
    ASSERT_TRUE(top.has_value()) << "fell through a closed surface" << at;
  }
  const Bracket bracket = index.bracket(u, v, h);
  ASSERT_TRUE(sameHit(bracket.below, below) && sameHit(bracket.above, above)) << "bracket" << at;
  const std::vector<Hit> all = index.all(u, v);
  checkAll(w, "all", all, xs, u, v, at, open);
  if (::testing::Test::HasFatalFailure()) return;
  // On a vertex or a shared edge several polygons hold the point at one height (to rounding):
  // top() may take any of them, all() lists each; elsewhere all() starts with top().
  const auto inAll = [&](const Hit& t) {
    return std::any_of(all.begin(), all.end(), [&](const Hit& a) { return a.polygon == t.polygon; }) &&
           std::fabs(t.height - all.front().height) <= w.tolerance;
  };
  ASSERT_TRUE(all.empty() ? !top : top && (open ? inAll(*top) : sameHit(all.front(), *top)))
      << "all().front() is top()" << at;
  ASSERT_TRUE(sameBits(index.height(u, v), top ? std::optional(top->height) : std::nullopt)) << "height" << at;
  ASSERT_TRUE(sameBits(index.heightBelow(u, v, h), below ? std::optional(below->height) : std::nullopt))
      << "heightBelow" << at;
  if (!withWorld) return;

  // The world point's line: the mapped queries at its mapped coordinates (the definition), and
  // the oracle's answer at (u, v) (the same line to rounding).
  const Eigen::Vector3d p = w.mapping.toWorld({u, v, h});
  Eigen::Vector3d m;
  try {
    m = w.mapping.toMapped(p);
  } catch (const Error&) {
    // A point the mapping cannot map back (its coordinates overflow on the way): no terrain.
    ASSERT_FALSE(index.topWorld(p) || index.belowWorld(p) || index.aboveWorld(p)) << "unmappable" << at;
    ASSERT_TRUE(index.allWorld(p).empty()) << "unmappable" << at;
    return;
  }
  const auto bw = index.belowWorld(p), aw = index.aboveWorld(p), tw = index.topWorld(p);
  ASSERT_TRUE(sameHit(bw, index.below(m.x(), m.y(), m.z()))) << "belowWorld" << at;
  ASSERT_TRUE(sameHit(aw, index.above(m.x(), m.y(), m.z()))) << "aboveWorld" << at;
  ASSERT_TRUE(sameHit(tw, index.top(m.x(), m.y()))) << "topWorld" << at;
  const Bracket bracketWorld = index.bracketWorld(p);
  ASSERT_TRUE(sameHit(bracketWorld.below, bw) && sameHit(bracketWorld.above, aw)) << "bracketWorld" << at;
  const std::vector<Hit> allWorld = index.allWorld(p);
  ASSERT_TRUE(sameHits(allWorld, index.all(m.x(), m.y()))) << "allWorld" << at;
  checkNearest(w, "topWorld", tw, true, kInf, xs, u, v, at, open);
  checkNearest(w, "belowWorld", bw, true, w.elevation(m.z()), xs, u, v, at, open);
  checkNearest(w, "aboveWorld", aw, false, w.elevation(m.z()), xs, u, v, at, open);
  checkAll(w, "allWorld", allWorld, xs, u, v, at, open);
}

// ---------------------------------------------------------------------------------------------

template <class T>
class IndexFace : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { world_ = std::make_unique<World<T>>(); }
  static void TearDownTestSuite() { world_.reset(); }
  static const World<T>& world() { return *world_; }
  static void report(const char* what, const Counts& n) {
    std::printf("[   counts ] %s %s: %d queries, %d with a clear answer, %d that must hit\n", T::kName, what, n.queries,
                n.clear, n.mustHit);
  }

 private:
  static inline std::unique_ptr<World<T>> world_;
};

TYPED_TEST_SUITE(IndexFace, AllIndexes, TraitsName);

// Random points over the terrain and around it, at random heights: every point and world query.
TYPED_TEST(IndexFace, RandomQueriesMatchTheOracle) {
  const auto& w = this->world();
  std::mt19937_64 rng(1);
  Counts n;
  for (int q = 0; q < 2000; ++q) {
    const Point2 p = w.drawUV(rng);
    checkPoint(w, p.u, p.v, w.drawH(rng), w.mustHit(p.u, p.v), true, n);
    if (this->HasFatalFailure()) return;
  }
  this->report("random", n);
  EXPECT_GT(n.clear, n.queries * 9 / 10);
}

// Exactly at vertices and on edges (within rounding of them, either side), at a vertex's own
// height too: either neighbour may answer, but where two polygons share the edge from opposite
// sides (and so at vertices all of whose edges are such) something must.
TYPED_TEST(IndexFace, VerticesAndSharedEdgesAreWatertight) {
  const auto& w = this->world();
  const Mesh& mesh = w.mesh;
  // Each edge of the fans (outline edges and fan diagonals), with the third corners beside it.
  std::map<std::pair<std::uint32_t, std::uint32_t>, std::vector<std::uint32_t>> edges;
  for (std::size_t p = 0; p < mesh.polygonCount(); ++p) {
    if (w.leftOut[p]) continue;
    const auto c = mesh.polygon(p);
    for (std::size_t k = 1; k + 1 < c.size(); ++k) {
      const std::uint32_t t[3] = {c[0], c[k], c[k + 1]};
      for (int e = 0; e < 3; ++e) {
        edges[std::minmax(t[e], t[(e + 1) % 3])].push_back(t[(e + 2) % 3]);
      }
    }
  }
  // Shared from opposite sides, seen along the line at the edge's midpoint.
  auto shared = [&](std::uint32_t a, std::uint32_t b, const std::vector<std::uint32_t>& thirds) {
    if (thirds.size() != 2) return false;
    const Eigen::Vector3d mid = w.mapping.toMapped(0.5 * (mesh.vertices[a] + mesh.vertices[b]));
    const Vec3L d = w.mapping.line(mid.x(), mid.y()).down.template cast<Real>();
    const Vec3L pa = mesh.vertices[a].cast<Real>(), ab = mesh.vertices[b].cast<Real>() - pa;
    Real s[2];
    for (int i = 0; i < 2; ++i) {
      const Vec3L ac = mesh.vertices[thirds[i]].cast<Real>() - pa;
      s[i] = ab.cross(ac).dot(d);
      if (std::fabs(s[i]) <= 1e-9L * ab.norm() * ac.norm()) return false;
    }
    return (s[0] > 0) != (s[1] > 0);
  };
  std::vector<std::pair<std::uint32_t, std::uint32_t>> list;
  std::vector<std::uint8_t> interiorEdge;
  std::vector<std::uint8_t> interiorVertex(mesh.vertices.size(), 0);
  for (const auto& [e, thirds] : edges) interiorVertex[e.first] = interiorVertex[e.second] = 1;
  for (const auto& [e, thirds] : edges) {
    list.push_back(e);
    interiorEdge.push_back(shared(e.first, e.second, thirds));
    if (!interiorEdge.back()) interiorVertex[e.first] = interiorVertex[e.second] = 0;
  }

  std::mt19937_64 rng(2);
  Counts n;
  auto query = [&](const Eigen::Vector3d& world, bool interior) {
    const Eigen::Vector3d m = w.mapping.toMapped(world);
    // At the point's own height (on the surface, to rounding) or a little off it.
    const double h = rng() % 2 ? m.z() : m.z() + uniform(rng, -0.02, 0.02) * (w.hhi - w.hlo);
    checkPoint(w, m.x(), m.y(), h, interior || w.mustHit(m.x(), m.y()), true, n);
  };
  std::vector<std::uint32_t> vertices(mesh.vertices.size());
  std::iota(vertices.begin(), vertices.end(), 0u);
  std::shuffle(vertices.begin(), vertices.end(), rng);
  vertices.resize(std::min<std::size_t>(vertices.size(), 700));
  for (std::uint32_t i : vertices) {
    query(mesh.vertices[i], interiorVertex[i]);
    if (this->HasFatalFailure()) return;
  }
  std::vector<std::size_t> order(list.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::shuffle(order.begin(), order.end(), rng);
  order.resize(std::min<std::size_t>(order.size(), 700));
  for (std::size_t k : order) {
    const Eigen::Vector3d a = mesh.vertices[list[k].first], b = mesh.vertices[list[k].second];
    for (const double s : {0.5, uniform(rng, 0, 1)}) {
      query(a + s * (b - a), interiorEdge[k]);
      if (this->HasFatalFailure()) return;
    }
  }
  this->report("vertices and edges", n);
  EXPECT_GT(n.mustHit, n.queries / 4);
}

// u = ulo and u = uhi (the seam) and u + k periods name one line; at a pole every u does.
TYPED_TEST(IndexFace, SeamAndPolesAreOneLine) {
  const auto& w = this->world();
  const auto& index = w.index;
  if (!w.domain.periodicU) GTEST_SKIP() << TypeParam::kName << " has no periodic axis and no poles";
  const double period = w.domain.uhi - w.domain.ulo;
  std::mt19937_64 rng(3);
  Counts n;
  auto expectOneLine = [&](double u0, double u1, double v, double h) {
    const At at{u0, v, h};
    ASSERT_TRUE(sameHit(index.top(u0, v), index.top(u1, v))) << "top, and u = " << u1 << at;
    ASSERT_TRUE(sameHit(index.below(u0, v, h), index.below(u1, v, h))) << "below, and u = " << u1 << at;
    ASSERT_TRUE(sameHit(index.above(u0, v, h), index.above(u1, v, h))) << "above, and u = " << u1 << at;
    ASSERT_TRUE(sameHits(index.all(u0, v), index.all(u1, v))) << "all, and u = " << u1 << at;
    ASSERT_TRUE(sameBits(index.heightBelow(u0, v, h), index.heightBelow(u1, v, h)))
        << "heightBelow, and u = " << u1 << at;
  };
  for (int i = 0; i < 300; ++i) {
    const double v = w.drawUV(rng).v, h = w.drawH(rng);
    // The seam, then any u exact in quarter degrees (so u + k periods is exact too).
    expectOneLine(w.domain.ulo, w.domain.uhi, v, h);
    expectOneLine(w.domain.ulo, w.domain.uhi + 2 * period, v, h);
    expectOneLine(w.domain.uhi, w.domain.ulo - 3 * period, v, h);
    const double u = w.domain.ulo + 0.25 * static_cast<double>(rng() % static_cast<std::uint64_t>(4 * period));
    expectOneLine(u, u + period, v, h);
    expectOneLine(u, u - 7 * period, v, h);
    if (this->HasFatalFailure()) return;
    checkPoint(w, w.domain.uhi, v, h, w.mustHit(w.domain.uhi, v), true, n);
    checkPoint(w, w.domain.ulo, v, h, w.mustHit(w.domain.ulo, v), true, n);
    if (this->HasFatalFailure()) return;
  }
  if (w.latitudes()) {
    for (const double pole : {w.domain.vlo, w.domain.vhi}) {
      for (int i = 0; i < 100; ++i) {
        const double u = i == 0   ? 0.0
                         : i < 50 ? uniform(rng, -540, 540)
                                  : 0.25 * static_cast<double>(rng() % 1441) - 180;
        const double h = w.drawH(rng);
        expectOneLine(0.0, u, pole, h);
        checkPoint(w, u, pole, h, true, true, n);
        if (this->HasFatalFailure()) return;
      }
    }
  }
  this->report("seam and poles", n);
}

// Off the terrain in an unbounded u or v, and far above or below it: no terrain, and the oracle
// agrees; u many periods away names a line still.
TYPED_TEST(IndexFace, FarOutsideIsNoTerrain) {
  const auto& w = this->world();
  const auto& index = w.index;
  std::mt19937_64 rng(4);
  Counts n;
  auto expectNone = [&](double u, double v, double h) {
    const At at{u, v, h};
    EXPECT_FALSE(index.top(u, v)) << at;
    EXPECT_FALSE(index.below(u, v, h)) << at;
    EXPECT_FALSE(index.above(u, v, h)) << at;
    EXPECT_TRUE(index.all(u, v).empty()) << at;
    EXPECT_FALSE(index.height(u, v)) << at;
    EXPECT_FALSE(index.heightBelow(u, v, h)) << at;
    EXPECT_TRUE(oracleAt(w, u, v).empty()) << "the oracle" << at;
    checkPoint(w, u, v, h, false, true, n);
  };
  const double du = w.box.uhi - w.box.ulo, dv = w.box.vhi - w.box.vlo;
  for (int i = 0; i < 50; ++i) {
    const Point2 p = w.drawUV(rng);
    const double h = w.drawH(rng);
    if (!std::isfinite(w.domain.uhi)) {
      for (const double u :
           {w.box.uhi + uniform(rng, 0.01, 10) * du, w.box.ulo - uniform(rng, 0.01, 1e6) * du, 1e300, -1e300}) {
        expectNone(u, p.v, h);
      }
    }
    if (!std::isfinite(w.domain.vhi)) {
      for (const double v :
           {w.box.vhi + uniform(rng, 0.01, 10) * dv, w.box.vlo - uniform(rng, 0.01, 1e6) * dv, 1e300, -1e300}) {
        expectNone(p.u, v, h);
      }
    }
    // Far below everything and far above it.
    const double span = w.hhi - w.hlo;
    const double low = w.fromElevation(std::min(w.elevation(w.hlo), w.elevation(w.hhi)) - 10 * span);
    const double high = w.fromElevation(std::max(w.elevation(w.hlo), w.elevation(w.hhi)) + 10 * span);
    const At at{p.u, p.v, low};
    EXPECT_FALSE(index.below(p.u, p.v, low)) << at;
    EXPECT_FALSE(index.heightBelow(p.u, p.v, low)) << at;
    EXPECT_FALSE(index.above(p.u, p.v, high)) << at;
    EXPECT_TRUE(sameHit(index.below(p.u, p.v, high), index.top(p.u, p.v))) << at;
    checkPoint(w, p.u, p.v, low, w.mustHit(p.u, p.v), false, n);
    checkPoint(w, p.u, p.v, high, w.mustHit(p.u, p.v), false, n);
    // Many periods away.
    if (w.domain.periodicU) {
      for (const double u : {1e6 + 0.25 * i, -3e9 - 0.5 * i, 1e15, 1e300}) {
        checkPoint(w, u, p.v, h, w.mustHit(u, p.v), false, n);
      }
    }
    if (this->HasFatalFailure()) return;
  }
  this->report("far outside", n);
}

// The policy of index.hpp: a query outside the mapping's domain or not finite has no terrain and
// throws nothing, alone or inside a batch, which answers its other points as ever.
TYPED_TEST(IndexFace, InvalidInputIsNoTerrainNotAnError) {
  const auto& w = this->world();
  const auto& index = w.index;
  // A valid point on the terrain: the middle of the first polygon kept.
  std::size_t p0 = 0;
  while (w.leftOut[p0]) ++p0;
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (std::uint32_t i : w.mesh.polygon(p0))
    centre += w.mesh.vertices[i] / static_cast<double>(w.mesh.polygon(p0).size());
  const Eigen::Vector3d m0 = w.mapping.toMapped(centre);
  const double u0 = m0.x(), v0 = m0.y(), h0 = m0.z();
  ASSERT_TRUE(index.top(u0, v0));

  std::vector<Point2> bad = {{kNaN, v0}, {u0, kNaN}, {kNaN, kNaN}, {kInf, v0}, {-kInf, v0}, {u0, kInf}, {u0, -kInf}};
  if (w.latitudes()) {
    for (const double v : {std::nextafter(w.domain.vhi, kInf), std::nextafter(w.domain.vlo, -kInf), w.domain.vhi + 1,
                           w.domain.vlo - 1, 2 * w.domain.vhi, 1e300, -1e300}) {
      bad.push_back({u0, v});
    }
  }
  Cursor cursor;
  for (const Point2& p : bad) {
    const At at{p.u, p.v, h0};
    EXPECT_NO_THROW({
      EXPECT_FALSE(index.top(p.u, p.v)) << at;
      EXPECT_FALSE(index.below(p.u, p.v, h0)) << at;
      EXPECT_FALSE(index.above(p.u, p.v, h0)) << at;
      const Bracket b = index.bracket(p.u, p.v, h0);
      EXPECT_FALSE(b.below || b.above) << at;
      EXPECT_TRUE(index.all(p.u, p.v).empty()) << at;
      EXPECT_FALSE(index.height(p.u, p.v)) << at;
      EXPECT_FALSE(index.heightBelow(p.u, p.v, h0)) << at;
      EXPECT_FALSE(index.below(cursor, p.u, p.v, h0)) << at;
      EXPECT_FALSE(index.above(cursor, p.u, p.v, h0)) << at;
      EXPECT_FALSE(index.height(cursor, p.u, p.v)) << at;
      EXPECT_FALSE(index.heightBelow(cursor, p.u, p.v, h0)) << at;
      (void)index.testsAt(p.u, p.v);
    });
  }
  // A NaN height: no terrain at or below it, nor above; the infinities are the ends of the line.
  const double topSide = w.fromElevation(kInf), bottomSide = w.fromElevation(-kInf);
  EXPECT_NO_THROW({
    EXPECT_FALSE(index.below(u0, v0, kNaN));
    EXPECT_FALSE(index.above(u0, v0, kNaN));
    const Bracket b = index.bracket(u0, v0, kNaN);
    EXPECT_FALSE(b.below || b.above);
    EXPECT_FALSE(index.heightBelow(u0, v0, kNaN));
    EXPECT_FALSE(index.below(cursor, u0, v0, kNaN));
    EXPECT_FALSE(index.heightBelow(cursor, u0, v0, kNaN));
  });
  EXPECT_TRUE(sameHit(index.below(u0, v0, topSide), index.top(u0, v0)));
  EXPECT_FALSE(index.below(u0, v0, bottomSide));
  EXPECT_FALSE(index.above(u0, v0, topSide));
  const std::vector<Hit> all = index.all(u0, v0);
  ASSERT_FALSE(all.empty());
  const auto lowest = index.above(u0, v0, bottomSide);
  ASSERT_TRUE(lowest);
  EXPECT_EQ(lowest->polygon, all.back().polygon);

  // World points that are not finite, or where the mapping has no (u, v).
  std::vector<Eigen::Vector3d> badWorld = {{kNaN, 0, 0}, {0, kNaN, 0},  {0, 0, kNaN},
                                           {kInf, 0, 0}, {0, -kInf, 0}, {0, 0, kInf}};
  for (const Eigen::Vector3d& p : TypeParam::singular(w.mapping)) badWorld.push_back(p);
  for (const Eigen::Vector3d& p : badWorld) {
    EXPECT_NO_THROW({
      EXPECT_FALSE(index.belowWorld(p)) << p.transpose();
      EXPECT_FALSE(index.aboveWorld(p)) << p.transpose();
      const Bracket b = index.bracketWorld(p);
      EXPECT_FALSE(b.below || b.above) << p.transpose();
      EXPECT_FALSE(index.topWorld(p)) << p.transpose();
      EXPECT_TRUE(index.allWorld(p).empty()) << p.transpose();
    });
  }
  // No line: not finite, or no direction.
  EXPECT_NO_THROW({
    EXPECT_TRUE(index.alongLine({kNaN, 0, 0}, {0, 0, 1}).empty());
    EXPECT_TRUE(index.alongLine(centre, {0, kInf, 1}).empty());
    EXPECT_TRUE(index.alongLine(centre, {0, 0, 0}).empty());
  });

  // Inside batches, between valid points: the same answers as alone, on every path.
  std::vector<Point2> points;
  std::vector<double> zs;
  std::mt19937_64 rng(5);
  for (int i = 0; i < 9000; ++i) {
    if (i % 3 == 0) {
      points.push_back(bad[static_cast<std::size_t>(i / 3) % bad.size()]);
    } else {
      points.push_back(i % 3 == 1 ? Point2{u0, v0} : w.drawUV(rng));
    }
    zs.push_back(i % 5 == 0 ? kNaN : i % 5 == 1 ? kInf : i % 5 == 2 ? -kInf : w.drawH(rng));
  }
  std::vector<std::optional<double>> out(points.size());
  EXPECT_NO_THROW(index.heightsBelowParallel(points, zs, out, 2));
  for (std::size_t i = 0; i < points.size(); ++i) {
    ASSERT_TRUE(sameBits(out[i], index.heightBelow(points[i].u, points[i].v, zs[i]))) << i;
    if (i % 3 == 0 || i % 5 == 0) {
      ASSERT_FALSE(out[i]) << i;
    }
  }
  EXPECT_NO_THROW(index.heights(points, out));
  for (std::size_t i = 0; i < points.size(); ++i) {
    ASSERT_TRUE(sameBits(out[i], index.height(points[i].u, points[i].v))) << i;
    if (i % 3 == 1) {
      ASSERT_TRUE(out[i]) << i;
    }
    if (i % 3 == 0) {
      ASSERT_FALSE(out[i]) << i;
    }
  }
}

// A cursor remembers its last leaf (and on a grid its last triangle): walks of small steps, across
// the seam and onto the poles, through invalid points and jumps, answer as the plain queries.
TYPED_TEST(IndexFace, CursorWalksAnswerAsPlainQueries) {
  const auto& w = this->world();
  const auto& index = w.index;
  std::mt19937_64 rng(6);
  const double stepU = w.domain.periodicU ? 0.4 : 0.004 * (w.box.uhi - w.box.ulo);
  const double stepV = w.latitudes() ? 0.4 : 0.004 * (w.box.vhi - w.box.vlo);
  Cursor cursor;
  Point2 p = w.drawUV(rng);
  int queries = 0;
  for (int i = 0; i < 8000; ++i) {
    if (i % 1000 == 999) p = w.drawUV(rng);    // a jump
    p.u += uniform(rng, -stepU, 1.5 * stepU);  // drifts across the seam without wrapping
    p.v += uniform(rng, -stepV, stepV);
    if (w.latitudes()) p.v = std::clamp(p.v, w.domain.vlo, w.domain.vhi);  // onto the poles exactly
    double u = p.u, v = p.v;
    if (i % 777 == 0) u = kNaN;
    const double h = w.drawH(rng);
    const At at{u, v, h};
    ASSERT_TRUE(sameHit(index.below(cursor, u, v, h), index.below(u, v, h))) << "step " << i << at;
    ASSERT_TRUE(sameHit(index.above(cursor, u, v, h), index.above(u, v, h))) << "step " << i << at;
    ASSERT_TRUE(sameBits(index.height(cursor, u, v), index.height(u, v))) << "step " << i << at;
    ASSERT_TRUE(sameBits(index.heightBelow(cursor, u, v, h), index.heightBelow(u, v, h))) << "step " << i << at;
    queries += 4;
  }
  std::printf("[   counts ] %s cursor: %d queries\n", TypeParam::kName, queries);
}

// heights and heightsBelow (one z, a z per point), on one thread or several, give the single
// queries' answers bit for bit: from a fresh index (a grid's lean state, before anything builds
// its tree) against the shared one, at random points, vertices, the seam, poles and invalid points.
TYPED_TEST(IndexFace, BatchesAnswerAsSingleQueriesBitForBit) {
  using T = TypeParam;
  const auto& w = this->world();
  const typename T::Index fresh(w.mesh, w.mapping, T::options());
  std::mt19937_64 rng(7);
  std::vector<Point2> points;
  std::vector<double> zs;
  for (int i = 0; i < 12000; ++i) {
    points.push_back(w.drawUV(rng));
    zs.push_back(w.drawH(rng));
  }
  for (std::size_t i = 0; i < w.mesh.vertices.size(); i += 5) {
    const Eigen::Vector3d m = w.mapping.toMapped(w.mesh.vertices[i]);
    points.push_back({m.x(), m.y()});
    zs.push_back(m.z());
  }
  for (const Point2& p : {Point2{w.domain.ulo, 10.0}, Point2{w.domain.uhi, -10.0}, Point2{kNaN, 0}, Point2{0, kNaN},
                          Point2{kInf, 0}, Point2{0, -kInf}, Point2{0, 100.0}, Point2{33, -100.0}}) {
    points.push_back(p);
    zs.push_back(w.drawH(rng));
  }
  if (w.latitudes()) {
    for (const Point2& p : {Point2{0, 90}, Point2{17.25, 90}, Point2{-180, -90}, Point2{123, -90}}) {
      points.push_back(p);
      zs.push_back(kInf);
    }
  }
  for (std::size_t i = 0; i < zs.size(); i += 97) zs[i] = i % 2 ? kNaN : -kInf;
  std::shuffle(points.begin() + 12000, points.end(), rng);
  const std::size_t n = points.size();
  const double z = w.fromElevation(0.5 * (w.elevation(w.hlo) + w.elevation(w.hhi)));

  std::vector<std::optional<double>> heights(n), below(n), belowEach(n), out(n);
  fresh.heights(points, heights);
  fresh.heightsBelow(points, z, below);
  fresh.heightsBelow(points, zs, belowEach);
  int hits = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double u = points[i].u, v = points[i].v;
    ASSERT_TRUE(sameBits(heights[i], w.index.height(u, v))) << "heights" << At{u, v, kInf};
    ASSERT_TRUE(sameBits(below[i], w.index.heightBelow(u, v, z))) << "heightsBelow" << At{u, v, z};
    ASSERT_TRUE(sameBits(belowEach[i], w.index.heightBelow(u, v, zs[i]))) << "heightsBelow(zs)" << At{u, v, zs[i]};
    hits += heights[i].has_value();
  }
  for (const double zz : {kInf, -kInf, kNaN}) {
    fresh.heightsBelow(points, zz, out);
    for (std::size_t i = 0; i < n; ++i) {
      ASSERT_TRUE(sameBits(out[i], w.index.heightBelow(points[i].u, points[i].v, zz)))
          << At{points[i].u, points[i].v, zz};
    }
  }
  for (const unsigned threads : {1u, 2u, 0u}) {
    fresh.heightsParallel(points, out, threads);
    ASSERT_TRUE(std::equal(out.begin(), out.end(), heights.begin(), [](auto& a, auto& b) { return sameBits(a, b); }))
        << threads << " threads";
    fresh.heightsBelowParallel(points, z, out, threads);
    ASSERT_TRUE(std::equal(out.begin(), out.end(), below.begin(), [](auto& a, auto& b) { return sameBits(a, b); }))
        << threads << " threads";
    fresh.heightsBelowParallel(points, zs, out, threads);
    ASSERT_TRUE(std::equal(out.begin(), out.end(), belowEach.begin(), [](auto& a, auto& b) { return sameBits(a, b); }))
        << threads << " threads";
  }
  // No room for every answer: an error before any work.
  std::vector<std::optional<double>> small(n - 1);
  const std::span<const double> fewZs(zs.data(), n - 1);
  EXPECT_THROW(fresh.heights(points, small), Error);
  EXPECT_THROW(fresh.heightsBelow(points, z, small), Error);
  EXPECT_THROW(fresh.heightsBelow(points, zs, small), Error);
  EXPECT_THROW(fresh.heightsBelow(points, fewZs, out), Error);
  EXPECT_THROW(fresh.heightsParallel(points, small, 2), Error);
  EXPECT_THROW(fresh.heightsBelowParallel(points, z, small, 2), Error);
  EXPECT_THROW(fresh.heightsBelowParallel(points, fewZs, out, 2), Error);
  std::printf("[   counts ] %s batches: %zu points (%d on terrain) x 9 batches x 4 ways\n", T::kName, n, hits);
  EXPECT_GT(hits, 0);
}

// alongLine: every crossing of any world line, nearest first, against the oracle per fan
// triangle (a line through a fan's diagonal meets both of its triangles). Random lines through
// the terrain, the mapping's own lines upward, lines from a vertex; whole and in a window.
TYPED_TEST(IndexFace, AlongLineMatchesTheOracle) {
  const auto& w = this->world();
  const auto& index = w.index;
  std::mt19937_64 rng(8);
  std::normal_distribution<double> g;
  Eigen::Vector3d lo = w.mesh.vertices[0], hi = lo;
  for (const auto& p : w.mesh.vertices) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  const double size = (hi - lo).norm(), tol = w.tolerance;
  int lines = 0, crossings = 0;
  auto check = [&](const Eigen::Vector3d& o, const Eigen::Vector3d& d, double tmin, double tmax) {
    const std::vector<LineHit> got = index.alongLine(o, d, tmin, tmax);
    const std::vector<Crossing> xs =
        w.oracle.triangles(o, d, [&](std::uint32_t p, std::span<const Vec3L> tri) { return w.keepTriangle(p, tri); });
    std::map<std::uint32_t, int> sure, maybe, count;
    for (const Crossing& x : xs) {
      const double t = static_cast<double>(x.t);
      if (t < tmin - tol || t > tmax + tol) continue;
      const bool isSure = x.margin > w.ambiguous && t > tmin + tol && t < tmax - tol;
      ++(isSure ? sure : maybe)[x.polygon];
    }
    ++lines;
    const std::string line = "line " + std::to_string(lines);
    for (std::size_t i = 0; i < got.size(); ++i) {
      const LineHit& lh = got[i];
      ++count[lh.hit.polygon];
      ASSERT_TRUE(lh.t >= tmin && lh.t <= tmax) << line;
      if (i > 0) {
        ASSERT_TRUE(got[i - 1].t < lh.t || (got[i - 1].t == lh.t && got[i - 1].hit.polygon <= lh.hit.polygon)) << line;
      }
      const bool onOracle = std::any_of(xs.begin(), xs.end(), [&](const Crossing& x) {
        // A line grazing a plane puts its crossing far along the line for a small error across it.
        // And the rounding of a point grows with its distance from the line's origin.
        const double across = std::max(std::fabs(x.normal.dot(d)), 1e-3);
        const double slack = tol * (1 + std::fabs(lh.t) / size) / across;
        return x.polygon == lh.hit.polygon && std::fabs(static_cast<double>(x.t) - lh.t) <= slack;
      });
      ASSERT_TRUE(onOracle) << line << ": polygon " << lh.hit.polygon << " at t = " << lh.t << " is not crossed";
      ASSERT_LE((lh.hit.world - (o + lh.t * d)).norm(), tol) << line;
      const Eigen::Vector3d m = w.mapping.toMapped(lh.hit.world);
      ASSERT_NEAR(lh.hit.height, m.z(), tol) << line;
      ASSERT_NEAR(lh.hit.normal.norm(), 1.0, 1e-12) << line;
      ASSERT_LE(lh.hit.normal.dot(w.mapping.line(m.x(), m.y()).down), 1e-9) << line << ": normal not up";
    }
    for (const auto& [p, k] : count) {
      ASSERT_LE(k, sure[p] + maybe[p]) << line << ": polygon " << p << " crossed " << k << " times";
    }
    for (const auto& [p, k] : sure) ASSERT_GE(count[p], k) << line << ": polygon " << p << " missed";
    crossings += static_cast<int>(got.size());
  };
  auto unit = [&] { return Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized(); };
  for (int i = 0; i < 60; ++i) {
    Eigen::Vector3d o, d;
    if (i < 30) {  // any line through the terrain's box
      o = lo + (hi - lo).cwiseProduct(Eigen::Vector3d(uniform(rng, 0, 1), uniform(rng, 0, 1), uniform(rng, 0, 1)));
      d = unit();
    } else if (i < 50) {  // the mapping's own line, upward from its origin
      const Point2 p = w.drawUV(rng);
      const MappedLine line = w.mapping.line(p.u, p.v);
      o = line.origin, d = -line.down;
    } else {  // from a vertex
      o = w.mesh.vertices[rng() % w.mesh.vertices.size()], d = unit();
    }
    check(o, d, -kInf, kInf);
    const double t0 = uniform(rng, -0.5, 0.2) * size;
    check(o, d, t0, t0 + uniform(rng, 0.1, 0.6) * size);
    if (this->HasFatalFailure()) return;
  }
  std::printf("[   counts ] %s alongLine: %d lines, %d crossings\n", TypeParam::kName, lines, crossings);
  EXPECT_GT(crossings, lines);
}

// What the index holds adds up: polygons, triangles, what is left out, the tree, the memory (a
// grid's lean state holds less until the tree is built), and a query's candidates.
TYPED_TEST(IndexFace, StatsAndMemoryAddUp) {
  using T = TypeParam;
  const auto& w = this->world();
  const typename T::Index index(w.mesh, w.mapping, T::options());
  if constexpr (requires { index.gridFastPath(); }) {
    EXPECT_EQ(index.gridFastPath(), T::kGridFastPath);
  }
  const std::uint64_t before = index.memoryBytesNow();
  EXPECT_GE(before, 8 * w.expectTriangles);  // something per triangle
  const IndexStats& s = index.stats();
  EXPECT_EQ(s.polygons, w.mesh.polygonCount());
  EXPECT_EQ(s.vertices, w.mesh.vertices.size());
  EXPECT_EQ(s.triangles, w.expectTriangles);
  EXPECT_EQ(s.leftOut, w.expectLeftOut);
  EXPECT_EQ(s.polarNorth + s.polarSouth > 0, w.latitudes());
  ASSERT_FALSE(s.domain.empty());
  for (std::size_t p = 0; p < w.mesh.polygonCount(); ++p) {
    if (w.leftOut[p]) continue;
    for (std::uint32_t i : w.mesh.polygon(p)) {
      const Eigen::Vector3d m = w.mapping.toMapped(w.mesh.vertices[i]);
      if (T::kParallelLines) {
        ASSERT_TRUE(s.domain.contains(m.x(), m.y())) << "vertex " << i;
      }
      if (!T::kParallelLines) {
        ASSERT_TRUE(m.y() >= s.domain.vlo && m.y() <= s.domain.vhi) << "vertex " << i;
      }
    }
  }
  EXPECT_GE(s.tree.nodes, 1u);
  EXPECT_GE(s.tree.leaves, 1u);
  EXPECT_LE(s.tree.leaves, s.tree.nodes);
  EXPECT_LE(s.tree.emptyLeaves, s.tree.leaves);
  EXPECT_GE(s.tree.references, s.triangles);  // every triangle in a leaf at least
  EXPECT_NEAR(s.tree.meanLeafItems * static_cast<double>(s.tree.leaves), static_cast<double>(s.tree.references),
              1e-9 * static_cast<double>(s.tree.references));
  EXPECT_LE(s.tree.depth, T::options().tree.maxDepth);
  EXPECT_GT(s.tree.averageTests, 0.0);
  EXPECT_GT(s.tree.memoryBytes, 0u);
  EXPECT_GT(s.memoryBytes, s.tree.memoryBytes);
  EXPECT_EQ(index.tree().stats().nodes, s.tree.nodes);
  EXPECT_EQ(index.memoryBytesNow(), s.memoryBytes);  // everything is built now
  if (T::kGridFastPath) {
    EXPECT_LT(before, s.memoryBytes);
  } else {
    EXPECT_EQ(before, s.memoryBytes);
  }
  std::mt19937_64 rng(9);
  for (int i = 0; i < 500; ++i) {
    const Point2 p = w.drawUV(rng);
    ASSERT_GE(index.testsAt(p.u, p.v), index.all(p.u, p.v).size()) << At{p.u, p.v, 0};
  }
  std::printf(
      "[   counts ] %s: %llu polygons, %llu triangles, %llu left out, %llu nodes, %.2f tests a query, "
      "%llu bytes (%llu before the deferred build)\n",
      T::kName, static_cast<unsigned long long>(s.polygons), static_cast<unsigned long long>(s.triangles),
      static_cast<unsigned long long>(s.leftOut), static_cast<unsigned long long>(s.tree.nodes), s.tree.averageTests,
      static_cast<unsigned long long>(s.memoryBytes), static_cast<unsigned long long>(before));
}

}  // namespace
