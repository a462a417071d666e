// planet_bench: QOTA queries in the curved mappings, next to the Cartesian index and a brute-force
// baseline measured in the same run.
//
// Terrains: the bundled global DEM (data/etopo20.tif) closed into an Earth-sized planet of about
// 1.17M triangles (spherical mapping); the bundled SRTM tile on the WGS84 ellipsoid (geodetic,
// 2.9M triangles); a 1M-triangle station (cylindrical); and, for comparison, a 1M-triangle
// fractal heightfield under the Cartesian mapping. Queries: 1M uniform random points (uniform on
// the sphere for the planet), and a coherent track of 100 m steps along a great circle (along the
// rows of the grid for the others), with and without a cursor (temporal coherence: the last
// leaf is remembered). Brute force: every triangle intersected with the query line
// (Moller-Trumbore in double precision), on a few hundred of the random points, whose answers are
// also checked against the index. Reports build seconds, ns per query and the ratio.
//
// Flags: --quick (the planet and the Cartesian terrain only, 100k queries).
#include <Eigen/Geometry>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <optional>
#include <limits>
#include <random>
#include <span>
#include <string>
#include <vector>

#include "qota/curved.hpp"
#include "qota/globe.hpp"
#include "qota/synthetic.hpp"
#include "qota/terrain.hpp"
#include "qota/treefile.hpp"
#include "qota/dem.hpp"
#include <filesystem>

namespace {

using Clock = std::chrono::steady_clock;
double seconds(Clock::time_point a, Clock::time_point b) { return std::chrono::duration<double>(b - a).count(); }

constexpr double kInf = std::numeric_limits<double>::infinity();

struct Query {
  double u, v;
};

// ns per query of f over the points (the sum of the answers is kept so nothing is optimized out).
template <class F>
double nsPerQuery(const std::vector<Query>& points, F&& f, int& misses) {
  double sum = 0;
  misses = 0;
  const auto t0 = Clock::now();
  for (const Query& q : points) {
    const std::optional<double> h = f(q.u, q.v);
    if (h)
      sum += *h;
    else
      ++misses;
  }
  const double ns = seconds(t0, Clock::now()) * 1e9 / static_cast<double>(points.size());
  if (sum == 1.2345) std::printf(" ");
  return ns;
}

// ns per query of a batch call over all points (in batches of 4096), checking every answer
// against the single query `one` (a difference counts as a disagreement).
template <class Batch, class One>
double nsPerBatch(const std::vector<Query>& points, Batch&& batch, One&& one, int& disagreements) {
  std::vector<qota::Point2> p(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) p[i] = {points[i].u, points[i].v};
  std::vector<std::optional<double>> out(points.size());
  constexpr std::size_t kBatch = 4096;
  const auto t0 = Clock::now();
  for (std::size_t i = 0; i < p.size(); i += kBatch) {
    const std::size_t k = std::min(kBatch, p.size() - i);
    batch(std::span<const qota::Point2>(p.data() + i, k), std::span<std::optional<double>>(out.data() + i, k));
  }
  const double ns = seconds(t0, Clock::now()) * 1e9 / static_cast<double>(p.size());
  for (std::size_t i = 0; i < p.size(); i += 97) disagreements += one(p[i].u, p[i].v) != out[i];
  return ns;
}

// Disagreements between the cursor and the plain query along a track (every 13th point).
template <class WithCursor, class Plain>
int checkCursor(const std::vector<Query>& track, WithCursor&& withCursor, Plain&& plain) {
  qota::Cursor cursor;
  int bad = 0;
  for (std::size_t i = 0; i < track.size(); ++i) {
    const auto a = withCursor(cursor, track[i].u, track[i].v);
    if (i % 13 == 0) bad += a != plain(track[i].u, track[i].v);
  }
  return bad;
}

// The line's top hit over every triangle: origin o, unit direction d toward increasing height,
// the hit's height as the parameter along d plus `offset`. Moller-Trumbore, both windings.
std::optional<double> bruteTop(const qota::Mesh& mesh, const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                               bool largest) {
  std::optional<double> best;
  const std::size_t n = mesh.polygonCount();
  for (std::size_t f = 0; f < n; ++f) {
    const auto p = mesh.polygon(f);
    const Eigen::Vector3d& a = mesh.vertices[p[0]];
    const Eigen::Vector3d e1 = mesh.vertices[p[1]] - a, e2 = mesh.vertices[p[2]] - a;
    const Eigen::Vector3d q = d.cross(e2);
    const double det = e1.dot(q);
    if (det == 0) continue;
    const double inv = 1.0 / det;
    const Eigen::Vector3d s = o - a;
    const double bu = s.dot(q) * inv;
    if (bu < 0 || bu > 1) continue;
    const Eigen::Vector3d r = s.cross(e1);
    const double bv = d.dot(r) * inv;
    if (bv < 0 || bu + bv > 1) continue;
    const double t = e2.dot(r) * inv;
    if (t <= 0) continue;
    if (!best || (largest ? t > *best : t < *best)) best = t;
  }
  return best;
}

struct Row {
  std::string mapping, terrain;
  std::size_t triangles;
  double build, random, batch, track, cursor, brute;
  int misses, disagreements, bruteQueries;
};

void printRow(const Row& r) {
  std::printf("%-11s %-22s %9zu %7.2f %8.0f %8.0f %8.0f %8.0f %10.0f %9.0fx %6d %6d/%d\n", r.mapping.c_str(),
              r.terrain.c_str(), r.triangles, r.build, r.random, r.batch, r.track, r.cursor, r.brute,
              r.brute / r.random, r.misses, r.disagreements, r.bruteQueries);
}

// Times one curved index: random and track queries, brute force on the first `bruteCount`
// random points (line from lineOf(u, v)), agreement within 1e-9 relative.
template <class Index, class LineOf>
Row measure(const std::string& mapping, const std::string& terrain, const qota::Mesh& mesh,
            std::function<Index()> build, const std::vector<Query>& random, const std::vector<Query>& track,
            int bruteCount, LineOf&& lineOf, bool largest) {
  Row row{mapping, terrain, mesh.polygonCount(), 0, 0, 0, 0, 0, 0, 0, 0, bruteCount};
  const auto t0 = Clock::now();
  const Index index = build();
  row.build = seconds(t0, Clock::now());
  int misses = 0;
  auto height = [&](double u, double v) { return index.height(u, v); };
  row.random = nsPerQuery(random, height, misses);
  row.misses = misses;
  row.batch = nsPerBatch(
      random, [&](auto points, auto out) { index.heights(points, out); },
      [&](double u, double v) { return index.height(u, v); }, row.disagreements);
  row.track = nsPerQuery(track, height, misses);
  row.misses += misses;
  qota::Cursor cursor;
  row.cursor = nsPerQuery(
      track, [&](double u, double v) { return index.height(cursor, u, v); }, misses);
  row.disagreements += checkCursor(
      track, [&](qota::Cursor& c, double u, double v) { return index.height(c, u, v); }, height);
  const auto b0 = Clock::now();
  for (int i = 0; i < bruteCount; ++i) {
    const auto [o, d, offset] = lineOf(random[i].u, random[i].v);
    const std::optional<double> t = bruteTop(mesh, o, d, largest);
    const std::optional<double> h = index.height(random[i].u, random[i].v);
    if (t.has_value() != h.has_value() || (t && std::fabs(*t + offset - *h) > 1e-9 * std::fabs(*t + offset) + 1e-6)) {
      ++row.disagreements;
    }
  }
  row.brute = seconds(b0, Clock::now()) * 1e9 / std::max(1, bruteCount);
  return row;
}

struct LineParts {
  Eigen::Vector3d o, d;
  double offset;  // height = t + offset
};

}  // namespace

// Tree files: build, write and load times of an index, and the file's size.
template <class Build>
void treeFileRow(const char* name, Build&& build) {
  const auto path = std::filesystem::temp_directory_path() / "planet_bench.qota";
  const auto t0 = Clock::now();
  const auto index = build();
  const auto t1 = Clock::now();
  qota::saveTree(path.string(), index);
  const auto t2 = Clock::now();
  const qota::TreeFile loaded = qota::loadTree(path.string());
  const auto t3 = Clock::now();
  const double mb = static_cast<double>(std::filesystem::file_size(path)) / 1e6;
  std::filesystem::remove(path);
  std::printf("%-34s %8.3f %8.3f %8.3f %9.1fx %9.1f\n", name, seconds(t0, t1), seconds(t1, t2), seconds(t2, t3),
              seconds(t0, t1) / seconds(t2, t3), mb);
}

int main(int argc, char** argv) {
  bool quick = false;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--quick")) quick = true;
  }
  const std::size_t n = quick ? 100000 : 1000000;
  const int bruteCount = quick ? 20 : 200;
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> unit(0, 1);
  std::printf("planet_bench: %zu random and %zu track queries per terrain, brute force on %d\n\n", n, n, bruteCount);
  std::printf("%-11s %-22s %9s %7s %8s %8s %8s %8s %10s %10s %6s %9s\n", "mapping", "terrain", "triangles", "build s",
              "random", "batch", "track", "+cursor", "brute", "brute/rnd", "misses", "disagree");
  std::printf("%-11s %-22s %9s %7s %8s %8s %8s %8s %10s\n", "", "", "", "", "ns/query", "ns/query", "ns/query",
              "ns/query", "ns/query");

  // Spherical: the planet, uniform random points on the sphere and a great-circle track.
  {
    const qota::PlanetTerrain planet = qota::loadPlanet(QOTA_DATA_DIR "/etopo20.tif");
    std::vector<Query> random(n), track(n);
    for (auto& q : random) {
      q = {-180 + 360 * unit(rng), std::asin(2 * unit(rng) - 1) * 180 / M_PI};
    }
    // A great circle inclined 60 degrees to the equator, 100 m steps (about 2.5 times around).
    const Eigen::Vector3d e1(1, 0, 0), e2(0, std::cos(M_PI / 3), std::sin(M_PI / 3));
    const double step = 100.0 / planet.radius;
    for (std::size_t i = 0; i < n; ++i) {
      const Eigen::Vector3d p = std::cos(i * step) * e1 + std::sin(i * step) * e2;
      track[i] = {qota::longitudeOf(p.x(), p.y()), std::atan2(p.z(), std::hypot(p.x(), p.y())) * 180 / M_PI};
    }
    printRow(measure<qota::SphericalIndex>(
        "spherical", "etopo20 planet", planet.dem.mesh,
        [&] { return qota::SphericalIndex(planet.dem.mesh, planet.mapping); }, random, track, bruteCount,
        [](double u, double v) {
          return LineParts{Eigen::Vector3d::Zero(), qota::SphericalMapping::up(u, v), 0.0};
        },
        true));
  }

  // Cartesian reference: a 1M-triangle fractal heightfield, random points and a row walk.
  {
    const int side = quick ? 225 : 708;
    const qota::Heightfield field = qota::fractalHeightfield(side, side, 1.0, 40.0, 5);
    const qota::Mesh mesh = field.toMesh();
    std::vector<Query> random(n), track(n);
    const double span = side - 1;
    for (auto& q : random) q = {span * unit(rng), span * unit(rng)};
    for (std::size_t i = 0; i < n; ++i) {
      const double along = std::fmod(0.1 * static_cast<double>(i), span);
      track[i] = {along, std::fmod(0.37 + std::floor(0.1 * i / span), span)};
    }
    // The same calls and the same work as the curved rows (measure): height, heights, a cursor.
    const qota::CartesianMapping mapping;
    printRow(measure<qota::CartesianIndex>(
        "cartesian", "fractal heightfield", mesh, [&] { return qota::CartesianIndex(mesh, mapping); }, random, track,
        bruteCount,
        [](double u, double v) {
          return LineParts{Eigen::Vector3d(u, v, -1e6), Eigen::Vector3d(0, 0, 1), -1e6};
        },
        true));
  }
  std::printf("\n%-34s %8s %8s %8s %10s %9s\n", "tree file (index only, terrain read)", "build s", "write s", "load s",
              "build/load", "MB");
  {
    const qota::PlanetTerrain planet = qota::loadPlanet(QOTA_DATA_DIR "/etopo20.tif");
    treeFileRow("spherical etopo20 planet", [&] { return qota::SphericalIndex(planet.dem.mesh, planet.mapping); });
  }
  if (quick) return 0;
  {
    const qota::DemTerrain dem = qota::loadDem(QOTA_DATA_DIR "/mt_rainier_90m.tif", {.lonLatAsCartesian = true});
    treeFileRow("cartesian SRTM Rainier", [&] { return qota::CartesianIndex(dem.mesh, dem.mapping); });
  }
  std::printf("\n");

  // Geodetic: the SRTM tile on WGS84, random points on the tile and a walk along a row.
  {
    const qota::EllipsoidTerrain t = qota::loadOnEllipsoid(QOTA_DATA_DIR "/mt_rainier_90m.tif");
    std::vector<Query> random(n), track(n);
    for (auto& q : random) q = {-122 + unit(rng), 46 + unit(rng)};
    for (std::size_t i = 0; i < n; ++i) {
      // 100 m steps east (0.0013 degrees of longitude at 46.5 N), row after row.
      const double lon = std::fmod(0.0013 * static_cast<double>(i), 1.0);
      track[i] = {-122 + lon, 46.1 + 0.0005 * std::floor(0.0013 * i)};
    }
    const qota::GeodeticMapping& m = t.mapping;
    printRow(measure<qota::GeodeticIndex>(
        "geodetic", "SRTM Rainier, WGS84", t.dem.mesh, [&] { return qota::GeodeticIndex(t.dem.mesh, m); }, random,
        track, bruteCount / 4,
        [&](double u, double v) {
          const qota::MappedLine line = m.line(u, v);
          return LineParts{line.origin, -line.down, 0.0};
        },
        true));
  }

  // Cylindrical: a 1M-triangle station (2000 columns around, 251 rings over 1 km).
  {
    const qota::Heightfield relief = qota::fractalHeightfield(2000, 251, 1.0, 8.0, 9);
    const qota::Mesh mesh = qota::stationMesh(relief, {250, 1000});
    std::vector<Query> random(n), track(n);
    for (auto& q : random) q = {-180 + 360 * unit(rng), -500 + 1000 * unit(rng)};
    for (std::size_t i = 0; i < n; ++i) {
      // 0.1 m steps around the hull (0.0229 degrees at 250 m), ring after ring.
      track[i] = {std::fmod(0.0229 * static_cast<double>(i), 360.0) - 180, -400 + 0.5 * std::floor(0.0229 * i / 360)};
    }
    const qota::CylindricalMapping m;
    printRow(measure<qota::CylindricalIndex>(
        "cylindrical", "station 250 m, 1 km", mesh, [&] { return qota::CylindricalIndex(mesh, m); }, random, track,
        bruteCount,
        [&](double u, double v) {
          const qota::MappedLine line = m.line(u, v);
          return LineParts{line.origin, line.down, 0.0};
        },
        false));
  }
  std::printf(
      "\nbrute: every triangle against the query line; disagree: brute and index heights "
      "differ by more than 1e-9 relative\n");
  return 0;
}
