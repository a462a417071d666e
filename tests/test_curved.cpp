// Curved mappings: round trips, the exact brute-force oracle, watertightness at vertices, poles
// and seams, and the planet, ellipsoid and station terrains.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include "qota/any_mapping.hpp"
#include "qota/curved.hpp"
#include "qota/error.hpp"
#include "qota/globe.hpp"
#include "qota/predicates.hpp"
#include "random_globe.hpp"

namespace {

using namespace qota;

double uniform(std::mt19937_64& rng, double lo, double hi) {
  return std::uniform_real_distribution<double>(lo, hi)(rng);
}
double randomLatitude(std::mt19937_64& rng) { return std::asin(uniform(rng, -1, 1)) * 180 / M_PI; }

// ---------------------------------------------------------------------------------------------
// Round trips: world -> mapped -> world to 1e-12 of the coordinates' magnitude.

TEST(CurvedMappings, SphericalRoundTrip) {
  std::mt19937_64 rng(11);
  std::normal_distribution<double> g;
  for (int i = 0; i < 100000; ++i) {
    const bool centred = i % 2 == 0;  // tiny radii need a centre at 0 to be resolvable
    const Eigen::Vector3d c = centred ? Eigen::Vector3d(Eigen::Vector3d::Zero())
                                      : Eigen::Vector3d(Eigen::Vector3d(g(rng), g(rng), g(rng)) * 1e3);
    Eigen::Vector3d dir(g(rng), g(rng), g(rng));
    if (i % 50 == 1) dir = Eigen::Vector3d(0, 0, i % 100 == 1 ? 1 : -1);  // poles
    if (i % 50 == 3) dir = Eigen::Vector3d(-1, 0, g(rng));                // on the seam
    const double r = std::pow(10.0, uniform(rng, centred ? -6 : 1, 9));
    const SphericalMapping m(c);
    const Eigen::Vector3d p = c + r * dir.normalized();
    const Eigen::Vector3d q = m.toMapped(p);
    ASSERT_GE(q.x(), -180.0);
    ASSERT_LT(q.x(), 180.0);
    ASSERT_LE(std::fabs(q.y()), 90.0);
    const double scale = std::max(p.norm(), c.norm());
    ASSERT_LE((m.toWorld(q) - p).norm(), 1e-12 * scale) << i;
  }
  const SphericalMapping m;
  EXPECT_EQ(m.toMapped({-1, 0, 0}).x(), -180.0);  // the seam is -180
  EXPECT_EQ(m.toMapped({0, 0, 5}), Eigen::Vector3d(0, 90, 5));
  EXPECT_EQ(SphericalMapping::up(123, 90), Eigen::Vector3d(0, 0, 1));  // exact at the pole
  EXPECT_THROW(m.toMapped({0, 0, 0}), Error);
}

TEST(CurvedMappings, CylindricalRoundTrip) {
  std::mt19937_64 rng(12);
  std::normal_distribution<double> g;
  for (int i = 0; i < 100000; ++i) {
    const bool simple = i % 2 == 0;
    const Eigen::Vector3d c = simple ? Eigen::Vector3d(Eigen::Vector3d::Zero())
                                     : Eigen::Vector3d(Eigen::Vector3d(g(rng), g(rng), g(rng)) * 100);
    const Eigen::Vector3d k = simple ? Eigen::Vector3d(0, 0, 1) : Eigen::Vector3d(g(rng), g(rng), g(rng));
    const CylindricalMapping m(c, k);
    const double scale = std::pow(10.0, uniform(rng, simple ? -6 : 1, 9));
    const Eigen::Vector3d mapped(i % 50 == 3 ? 180.0 : uniform(rng, -180, 180), uniform(rng, -1, 1) * scale,
                                 uniform(rng, 0.01, 1) * scale);
    const Eigen::Vector3d p = m.toWorld(mapped);
    const Eigen::Vector3d q = m.toMapped(p);
    ASSERT_GE(q.x(), -180.0);
    ASSERT_LT(q.x(), 180.0);
    ASSERT_LE((m.toWorld(q) - p).norm(), 1e-12 * std::max(p.norm(), c.norm())) << i;
  }
  const CylindricalMapping m({1, 2, 3}, {0, 1, 0});
  try {
    m.toMapped({1, 50, 3});
    FAIL() << "a point on the axis must be an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("on the axis"), std::string::npos) << e.what();
  }
  EXPECT_THROW(CylindricalMapping({0, 0, 0}, {0, 0, 0}), Error);
}

TEST(CurvedMappings, GeodeticRoundTrip) {
  std::mt19937_64 rng(13);
  for (double a : {6378137.0, 1.0, 1e9}) {
    const GeodeticMapping m(a, a == 6378137.0 ? 1 / 298.257223563 : 0.1);
    for (int i = 0; i < 100000 / 3; ++i) {
      double lat = randomLatitude(rng), lon = uniform(rng, -180, 180);
      if (i % 50 == 1) lat = i % 100 == 1 ? 90 : -90;
      if (i % 50 == 3) lon = -180;
      const Eigen::Vector3d p = m.toWorld({lon, lat, uniform(rng, -0.001, 0.02) * a});
      const Eigen::Vector3d q = m.toMapped(p);
      ASSERT_GE(q.x(), -180.0);
      ASSERT_LT(q.x(), 180.0);
      ASSERT_LE((m.toWorld(q) - p).norm(), 1e-12 * p.norm()) << a << " " << i;
    }
  }
  // A point on the ellipsoid maps to height 0 and its own latitude.
  const GeodeticMapping wgs;
  const Eigen::Vector3d q = wgs.toMapped(wgs.toWorld({-121.76, 46.85, 0}));
  EXPECT_NEAR(q.x(), -121.76, 1e-12);
  EXPECT_NEAR(q.y(), 46.85, 1e-12);
  EXPECT_NEAR(q.z(), 0, 1e-8);
  // The line of (u, v) is the normal: its origin is on the surface, its points keep (u, v).
  const MappedLine line = wgs.line(30, 60);
  const Eigen::Vector3d up = wgs.toMapped(line.origin - 1000 * line.down);
  EXPECT_NEAR(up.x(), 30, 1e-12);
  EXPECT_NEAR(up.y(), 60, 1e-12);
  EXPECT_NEAR(up.z(), 1000, 1e-8);
  EXPECT_THROW(GeodeticMapping(-1, 0), Error);
}

TEST(CurvedMappings, DescribeParsesBack) {
  const AnyMapping all[] = {CartesianMapping({0.1, 0.2, -1}, {1e6, 2e6, 3}), SphericalMapping({1, 2, 3}),
                            CylindricalMapping({0, 1, 2}, {1, 1, 0}), GeodeticMapping(3396190, 0.005)};
  for (const AnyMapping& m : all) {
    const std::string text = describe(m);
    EXPECT_EQ(describe(parseMapping(text)), text);
  }
  EXPECT_EQ(mappingName(parseMapping("geodetic")), std::string("geodetic"));
  EXPECT_THROW(parseMapping("spherical centre=1,2"), Error);
  EXPECT_THROW(parseMapping("conical"), Error);
  EXPECT_THROW(parseMapping("geodetic a=-1"), Error);
  EXPECT_THROW(parseMapping("spherical radius=3"), Error);
}

TEST(CurvedMappings, ExactOrient3d) {
  // Exactly coplanar triples (d = a + b in exact arithmetic) are 0, and swapping a and b negates.
  std::mt19937_64 rng(14);
  for (int i = 0; i < 10000; ++i) {
    double a[3], b[3], d[3];
    for (int k = 0; k < 3; ++k) {
      a[k] = std::ldexp(std::round(uniform(rng, -1e6, 1e6)), -10);
      b[k] = std::ldexp(std::round(uniform(rng, -1e6, 1e6)), -10);
      d[k] = a[k] + b[k];  // exact: both are multiples of 2^-10 below 2^20
    }
    ASSERT_EQ(orient3dSign(a, b, d), 0);
    d[0] = std::nextafter(d[0], 1e300);
    ASSERT_EQ(orient3dSign(a, b, d), -orient3dSign(b, a, d));
    ASSERT_NE(orient3dSign(a, b, d), 0);
  }
}

// ---------------------------------------------------------------------------------------------
// The oracle: the mapping's own line (MappedLine, in the world frame) intersected with every
// triangle, the hit's height measured back through the mapping's toMapped.

struct OracleHit {
  bool found = false;
  double h = 0;
  std::uint32_t polygon = 0;
};

// Each triangle's bounding sphere (centroid, radius): a line farther from the centroid than the
// radius (with a wide margin for rounding) cannot meet the triangle, so the exact test is skipped.
// Only a time saving: every triangle the line may meet still takes the exact test below.
struct TriangleSpheres {
  std::vector<Eigen::Vector3d> centre;
  std::vector<double> radius;
  explicit TriangleSpheres(const Mesh& mesh) {
    for (std::size_t poly = 0; poly < mesh.polygonCount(); ++poly) {
      const auto idx = mesh.polygon(poly);
      const Eigen::Vector3d m = (mesh.vertices[idx[0]] + mesh.vertices[idx[1]] + mesh.vertices[idx[2]]) / 3;
      double r = 0;
      for (int k = 0; k < 3; ++k) r = std::max(r, (mesh.vertices[idx[k]] - m).norm());
      centre.push_back(m), radius.push_back(r);
    }
  }
  bool mayMeet(std::size_t poly, const Eigen::Vector3d& origin, const Eigen::Vector3d& unitDir) const {
    const Eigen::Vector3d w = centre[poly] - origin;
    return w.cross(unitDir).norm() <= radius[poly] * (1 + 1e-6) + 1e-9 * w.norm();
  }
};

template <class M>
OracleHit oracleBelow(const Mesh& mesh, const TriangleSpheres& spheres, const M& mapping, double u, double v,
                      double hq) {
  const MappedLine line = mapping.line(u, v);
  const Eigen::Vector3d dir = M::kHeightUp ? Eigen::Vector3d(-line.down) : line.down;
  const Eigen::Vector3d unitDir = dir.normalized();
  const double ez = M::kHeightUp ? hq : -hq;
  OracleHit best;
  double bestE = 0;
  for (std::size_t poly = 0; poly < mesh.polygonCount(); ++poly) {
    if (!spheres.mayMeet(poly, line.origin, unitDir)) continue;
    const auto idx = mesh.polygon(poly);
    const Eigen::Vector3d a = mesh.vertices[idx[0]] - line.origin;
    const Eigen::Vector3d b = mesh.vertices[idx[1]] - line.origin;
    const Eigen::Vector3d c = mesh.vertices[idx[2]] - line.origin;
    const int s0 = orient3dSign(a.data(), b.data(), dir.data());
    const int s1 = orient3dSign(b.data(), c.data(), dir.data());
    const int s2 = orient3dSign(c.data(), a.data(), dir.data());
    const bool neg = s0 < 0 || s1 < 0 || s2<0, pos = s0> 0 || s1 > 0 || s2 > 0;
    if ((neg && pos) || (!neg && !pos)) continue;
    const Eigen::Vector3d n = (b - a).cross(c - a);
    const double t = n.dot(a) / n.dot(dir);
    const Eigen::Vector3d p = line.origin + t * dir;
    // The half-line: beyond the centre or axis point (for the ellipsoid, the normal's axis
    // crossing lies below the surface origin).
    if (!std::isfinite(t)) continue;
    const double h = mapping.toMapped(p).z();
    if constexpr (std::is_same_v<M, GeodeticMapping>) {
      if (t + mapping.primeVerticalRadius(v) <= 0) continue;
    } else {
      if (t <= 0) continue;
    }
    const double e = M::kHeightUp ? h : -h;
    if (e > ez) continue;
    if (!best.found || e > bestE || (e == bestE && poly < best.polygon)) {
      best = {true, h, static_cast<std::uint32_t>(poly)};
      bestE = e;
    }
  }
  return best;
}

template <class M>
void expectMatchesOracle(const Mesh& mesh, const M& mapping, const CurvedIndex<M>& index, int queries,
                         std::uint64_t seed, double vlo, double vhi, double absTolerance = 0) {
  std::mt19937_64 rng(seed);
  const TriangleSpheres spheres(mesh);
  int polygonMismatches = 0;
  for (int q = 0; q < queries; ++q) {
    const double u = uniform(rng, -180, 180);
    const double v = vlo == -90 ? randomLatitude(rng) : uniform(rng, vlo, vhi);
    // Half the queries from far above (the top surface), half from a random level.
    const auto topOf = index.top(u, v);
    ASSERT_TRUE(topOf.has_value()) << "closed surface missed at " << u << " " << v;
    const double hq = q % 2 ? (M::kHeightUp ? 1e300 : -1e300) : topOf->height * uniform(rng, 0.999, 1.001);
    const OracleHit o = oracleBelow(mesh, spheres, mapping, u, v, hq);
    const auto hit = index.below(u, v, hq);
    ASSERT_EQ(hit.has_value(), o.found) << u << " " << v << " " << hq;
    if (!o.found) continue;
    const double tol = absTolerance > 0 ? absTolerance : 1e-9 * std::fabs(o.h);
    ASSERT_NEAR(hit->height, o.h, tol) << u << " " << v;
    polygonMismatches += hit->polygon != o.polygon;
    // The world point is on the line and maps back to (u, v, h).
    const Eigen::Vector3d back = mapping.toMapped(hit->world);
    ASSERT_NEAR(back.z(), hit->height, std::max(tol, 1e-9 * std::fabs(hit->height)));
  }
  EXPECT_EQ(polygonMismatches, 0);
}

// Queries exactly at vertices (their mapped u, v), at edge midpoints, on the seam and at the
// poles: a closed surface must always be hit. Returns the misses.
template <class M>
int missesAtFeatures(const Mesh& mesh, const M& mapping, const CurvedIndex<M>& index, std::uint64_t seed, bool poles) {
  std::mt19937_64 rng(seed);
  int misses = 0;
  // An open surface (a tube) may round outside at its rims: those are not counted.
  const double vlo = index.stats().domain.vlo, vhi = index.stats().domain.vhi;
  const double rim = poles ? 0.0 : 1e-6 * (vhi - vlo);
  auto interior = [&](double v) { return v >= vlo + rim && v <= vhi - rim; };
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
    const Eigen::Vector3d m = mapping.toMapped(mesh.vertices[i]);
    if (!interior(m.y())) continue;
    const auto hit = index.top(m.x(), m.y());
    if (!hit) {
      if (++misses < 5) ADD_FAILURE() << "vertex " << i << " at (" << m.x() << ", " << m.y() << ")";
      continue;
    }
    // Relative to the height and to the coordinates' magnitude (h = t - N on an ellipsoid).
    EXPECT_NEAR(hit->height, m.z(), 1e-9 * std::fabs(m.z()) + 1e-14 * mesh.vertices[i].norm());
  }
  for (std::size_t f = 0; f < mesh.polygonCount(); ++f) {
    const auto p = mesh.polygon(f);
    const Eigen::Vector3d mid = 0.5 * (mesh.vertices[p[0]] + mesh.vertices[p[1]]);
    const Eigen::Vector3d m = mapping.toMapped(mid);
    if (!interior(m.y())) continue;
    if (!index.top(m.x(), m.y()) && ++misses < 5) {
      ADD_FAILURE() << "edge of polygon " << f << " at (" << m.x() << ", " << m.y() << ")";
    }
  }
  for (int i = 0; i < 2000; ++i) {
    const double v = uniform(rng, vlo + rim, vhi - rim);
    const auto east = index.top(180.0, v), west = index.top(-180.0, v);
    misses += !east.has_value() + !west.has_value();
    if (!east || !west) {
      ADD_FAILURE() << "seam at v = " << v;
    } else {
      EXPECT_EQ(east->height, west->height);
    }
  }
  if (poles) {
    for (double v : {90.0, -90.0}) {
      const auto first = index.top(0, v);
      misses += !first.has_value();
      for (int i = 0; i < 100 && first; ++i) {
        const auto hit = index.top(uniform(rng, -540, 540), v);
        misses += !hit.has_value();
        if (hit) {
          EXPECT_EQ(hit->height, first->height);
        }
      }
    }
  }
  return misses;
}

Mesh bumpySphere(int level, double radius, double bump, std::uint64_t seed, bool rotate) {
  std::mt19937_64 rng(seed);
  Mesh m = test::unitIcosphere(level, rng, rotate);
  for (auto& p : m.vertices) p *= radius * (1 + bump * uniform(rng, -1, 1));
  return m;
}

TEST(CurvedIndex, SphereMatchesOracle) {
  for (const bool rotate : {true, false}) {
    const Mesh mesh = bumpySphere(7, 1000.0, 0.02, rotate ? 21 : 22, rotate);  // 327,680 triangles
    const SphericalMapping mapping;
    const SphericalIndex index(mesh, mapping);
    EXPECT_EQ(index.stats().triangles, 327680u);
    expectMatchesOracle(mesh, mapping, index, 150, 23, -90, 90);
    EXPECT_EQ(missesAtFeatures(mesh, mapping, index, 24, true), 0);
    if (!rotate) {
      EXPECT_GT(index.stats().polarNorth, 0u);
    }
  }
}

// Walks through a cursor over a sphere's tree larger than a cache holds, where the cursor fetches
// the leaves ahead of a walk: runs of small steps in longitude and latitude, turns, reversals,
// across the seam and near the poles, answer as the plain queries (which the oracle holds above).
TEST(CurvedIndex, LongCursorWalksAnswerAsPlainQueries) {
  const Mesh mesh = bumpySphere(7, 1000.0, 0.02, 21, true);
  const SphericalIndex index(mesh, SphericalMapping());
  ASSERT_GT(index.stats().tree.memoryBytes, std::uint64_t{8} << 20) << "too small a tree to fetch ahead";
  std::mt19937_64 rng(28);
  Cursor cursor;
  double u = 170, v = 10, du = 0.01, dv = 0.003;
  for (int i = 0; i < 120000; ++i) {
    if (i % 3000 == 0) {  // a new course: steps from a thousandth of a degree to a few degrees
      const double length = std::pow(10.0, uniform(rng, -3, 0.6)), angle = uniform(rng, 0, 2 * M_PI);
      du = length * std::cos(angle), dv = length * std::sin(angle);
    }
    if (i % 3000 == 1500) du = -du, dv = -dv;
    u += du, v += dv;
    if (u > 180) u -= 360;  // across the seam
    if (u < -180) u += 360;
    if (v > 89.5 || v < -89.5) dv = -dv, v = std::clamp(v, -89.5, 89.5);
    const double h = i % 3 == 0 ? 2000.0 : 1000 * uniform(rng, 0.97, 1.03);
    ASSERT_EQ(index.heightBelow(cursor, u, v, h), index.heightBelow(u, v, h))
        << "step " << i << " at " << u << " " << v;
    if (i % 5 == 0) {
      const auto a = index.below(cursor, u, v, h), b = index.below(u, v, h);
      ASSERT_EQ(a.has_value(), b.has_value()) << "step " << i;
      if (a) {
        ASSERT_EQ(a->polygon, b->polygon) << "step " << i;
      }
    }
  }
}

TEST(CurvedIndex, EarthSizedSphereToAMillimetre) {
  const double R = 6371008.8;
  const Mesh mesh = bumpySphere(7, R, 9000.0 / R, 25, true);
  const Eigen::Vector3d centre(1e3, -2e3, 5e2);  // an offset centre exercises the local frame
  Mesh moved = mesh;
  for (auto& p : moved.vertices) p += centre;
  const SphericalMapping mapping(centre);
  const SphericalIndex index(moved, mapping);
  expectMatchesOracle(moved, mapping, index, 150, 26, -90, 90, 1e-3);
  EXPECT_EQ(missesAtFeatures(moved, mapping, index, 27, true), 0);
}

TEST(CurvedIndex, EllipsoidMatchesOracle) {
  std::mt19937_64 rng(31);
  const GeodeticMapping mapping;  // WGS84
  Mesh mesh = test::unitIcosphere(7, rng, true);
  for (auto& p : mesh.vertices) {
    const double lon = longitudeOf(p.x(), p.y());
    const double lat = std::atan2(p.z(), std::hypot(p.x(), p.y())) * 180 / M_PI;
    p = mapping.toWorld({lon, lat, uniform(rng, -500, 9000)});
  }
  const GeodeticIndex index(mesh, mapping);
  expectMatchesOracle(mesh, mapping, index, 150, 32, -90, 90, 1e-3);
  EXPECT_EQ(missesAtFeatures(mesh, mapping, index, 33, true), 0);
}

TEST(CurvedIndex, CylinderMatchesOracle) {
  std::mt19937_64 rng(41);
  Mesh mesh = test::bumpyTube(500, 101, 250.0, 1000.0, 0.03, rng);  // 100,000 triangles
  // A tilted, offset axis.
  const Eigen::Vector3d point(10, -20, 30), axis = Eigen::Vector3d(0.3, -0.2, 1).normalized();
  const Eigen::Quaterniond q = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d(0, 0, 1), axis);
  for (auto& p : mesh.vertices) p = q * p + point;
  const CylindricalMapping mapping(point, axis);
  const CylindricalIndex index(mesh, mapping);
  EXPECT_EQ(index.stats().triangles, 100000u);
  expectMatchesOracle(mesh, mapping, index, 300, 42, -499, 499);
  EXPECT_EQ(missesAtFeatures(mesh, mapping, index, 43, false), 0);
  // "Below" is away from the axis: from the axis outward the floor is found, from beyond it none.
  const auto floor = index.below(10, 0, 0.0);
  ASSERT_TRUE(floor);
  EXPECT_FALSE(index.below(10, 0, 300.0));
  EXPECT_TRUE(index.above(10, 0, 300.0));
}

TEST(CurvedIndex, BadInput) {
  Mesh mesh;
  mesh.addVertex({1, 0, 0});
  mesh.addVertex({0, 1, 0});
  mesh.addTriangle(0, 1, 2);
  EXPECT_THROW(SphericalIndex(mesh, SphericalMapping()), Error);
  mesh.addVertex({0, 0, NAN});
  EXPECT_THROW(SphericalIndex(mesh, SphericalMapping()), Error);
  mesh.vertices[2] = {0, 0, 1};
  const SphericalIndex index(mesh, SphericalMapping());
  EXPECT_FALSE(index.top(0, 91).has_value());  // beyond the pole: no terrain, no exception (index.hpp)
  EXPECT_FALSE(index.top(NAN, 0).has_value());
  EXPECT_FALSE(index.below(0, 30, NAN).has_value());
  IndexOptions grid;
  grid.gridFastPath = true;
  EXPECT_THROW(SphericalIndex(mesh, SphericalMapping(), grid), Error);  // not for a curved mapping
  EXPECT_TRUE(index.top(30, 30).has_value());
  EXPECT_FALSE(index.top(-150, -30).has_value());  // a hole: the rest of the sphere is empty
}

// ---------------------------------------------------------------------------------------------
// Terrains: the bundled global DEM as a closed planet, an SRTM tile on the WGS84 ellipsoid.

TEST(Globe, Etopo20IsAClosedPlanet) {
  const PlanetTerrain planet = loadPlanet(QOTA_DATA_DIR "/etopo20.tif");
  EXPECT_TRUE(planet.wrapsLongitude);
  EXPECT_TRUE(planet.northCap);
  EXPECT_TRUE(planet.southCap);
  EXPECT_NEAR(planet.radius, 6371008.77, 0.01);  // WGS84 mean radius from the CRS
  const SphericalIndex index(planet.dem.mesh, planet.mapping);
  std::mt19937_64 rng(51);
  int misses = 0;
  for (int i = 0; i < 100000; ++i) {
    misses += !index.height(uniform(rng, -180, 180), randomLatitude(rng)).has_value();
  }
  EXPECT_EQ(misses, 0);
  // Pixel centres carry the raster's values; the published spot checks of the data.
  const auto h = [&](double lon, double lat) { return *index.height(lon, lat) - planet.radius; };
  const auto& dem = planet.dem;
  for (int k = 0; k < 2000; ++k) {
    const int c = static_cast<int>(uniform(rng, 0, dem.width)), r = static_cast<int>(uniform(rng, 0, dem.height));
    const auto xy = dem.pixelCentre(c, r);
    const Eigen::Vector3d m = planet.mapping.toMapped(dem.mesh.vertices[static_cast<std::size_t>(r) * dem.width + c]);
    ASSERT_NEAR(h(xy[0], xy[1]) + planet.radius, m.z(), 1e-6);
  }
  EXPECT_NEAR(h(-40.0 + 1 / 6.0, 75.0 - 1 / 6.0), 2895, 60);  // Greenland ice
  EXPECT_LT(h(142.5, 11.3), -8000);                           // Mariana trench
  EXPECT_EQ(missesAtFeatures(planet.dem.mesh, planet.mapping, index, 52, true), 0);

  // The batched query gives the single query's answers, poles and seams included.
  std::vector<Point2> points(20000);
  for (auto& p : points) p = {uniform(rng, -540, 540), randomLatitude(rng)};
  points[0] = {0, 90}, points[1] = {17, -90}, points[2] = {180, 10}, points[3] = {-180, 10};
  std::vector<std::optional<double>> out(points.size());
  index.heights(points, out);
  for (std::size_t i = 0; i < points.size(); ++i) {
    ASSERT_EQ(out[i], index.height(points[i].u, points[i].v)) << i;
  }
}

TEST(Globe, SrtmOnTheEllipsoid) {
  DemOptions overEllipsoid;  // (heights over EGM96, as SRTM's are: test_geoid.cpp)
  overEllipsoid.heightRef = "ellipsoid";
  const EllipsoidTerrain t = loadOnEllipsoid(QOTA_DATA_DIR "/mt_rainier_90m.tif", overEllipsoid);
  const GeodeticIndex index(t.dem.mesh, t.mapping);
  std::mt19937_64 rng(61);
  for (int k = 0; k < 5000; ++k) {
    const int c = static_cast<int>(uniform(rng, 0, t.dem.width)), r = static_cast<int>(uniform(rng, 0, t.dem.height));
    const auto xy = t.dem.pixelCentre(c, r);
    const Eigen::Vector3d& p = t.dem.mesh.vertices[static_cast<std::size_t>(r) * t.dem.width + c];
    if (!std::isfinite(p.z())) continue;
    const auto h = index.height(xy[0], xy[1]);
    if (!h) continue;  // a vertex whose every triangle touches nodata
    ASSERT_NEAR(*h, t.mapping.toMapped(p).z(), 1e-6);
  }
  const auto summit = index.height(-121.7603, 46.8529);
  ASSERT_TRUE(summit);
  EXPECT_NEAR(*summit, 4367, 10);
  EXPECT_FALSE(index.height(-123.5, 46.5).has_value());                     // off the tile
  EXPECT_THROW(loadOnEllipsoid(QOTA_DATA_DIR "/SainteHelens.dem"), Error);  // UTM, not lon/lat
}

TEST(Globe, StationIsClosedAroundTheAxis) {
  Heightfield relief = fractalHeightfield(360, 50, 1.0, 8.0, 3);
  const Mesh mesh = stationMesh(relief, {250, 1000});
  const CylindricalIndex index(mesh, CylindricalMapping());
  EXPECT_EQ(missesAtFeatures(mesh, CylindricalMapping(), index, 71, false), 0);
  relief.z[5] = 300;  // reaches past the axis
  EXPECT_THROW(stationMesh(relief, {250, 1000}), Error);
}

}  // namespace
