// qota_bench: how fast QOTA terrain queries are, measured against the two answers a user would
// otherwise write: direct indexing of the height grid (the fastest possible, but only for a regular
// grid) and testing every triangle (all a polygon soup allows without an index).
//
// Terrains: fractal heightfields of about 13k and 1M triangles, and the bundled SRTM tile of
// Mount Rainier (about 2.9M triangles). Each terrain is loaded, benchmarked and released in turn,
// so the large ones never occupy memory together. Google Benchmark does the timing (one iteration
// is one query, or one index build); a collecting reporter keeps each run's real time per
// iteration for the summary table printed at the end, next to how far the qota heights are from
// the baseline heights on the same query points.
//
// Flags: every --benchmark_* flag of Google Benchmark (the minimum time defaults to 0.3 s here;
// --benchmark_min_time overrides it), plus --quick: only the small synthetic terrain.

#include <benchmark/benchmark.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <numbers>
#include <optional>
#include <random>
#include <regex>
#include <stdexcept>
#include <string>
#include <variant>
#include <vector>

#include "qota/dem.hpp"
#include "qota/synthetic.hpp"
#include "qota/terrain.hpp"

namespace {

// At least a million query points per set, a power of two so the sets cycle evenly.
constexpr std::size_t kQueryCount = std::size_t{1} << 20;
// Put before the user's arguments, so a --benchmark_min_time of theirs wins (the last one counts).
constexpr const char* kDefaultMinTime = "--benchmark_min_time=0.3";
// Heights farther apart than this fraction of the terrain's relief are reported as disagreeing.
constexpr double kRelativeTolerance = 1e-6;
constexpr double kInf = std::numeric_limits<double>::infinity();

struct Point {
  double u, v;  // mapped frame
};

// ---------------------------------------------------------------------------------------------
// Baselines, both in the mapped frame. Each returns the surface height at (u, v), or nothing off
// the surface.

// A synthetic heightfield under the default mapping (gravity -Z, origin 0), so u = x and v = y:
// its own heightAt is the direct-indexing answer, on the same triangulation as its mesh.
struct HeightfieldLookup {
  qota::Heightfield field;
  std::optional<double> operator()(double u, double v) const {
    double h = 0;
    if (!field.heightAt(u, v, h)) return std::nullopt;
    return h;
  }
};

// A raster read by loadDem: pixel coordinates from the inverse geotransform, then the same split
// as loadDem's, along the diagonal from (col, row) to (col + 1, row + 1). A nodata corner is NaN,
// which propagates, so a cell side touching nodata is a hole, as in the mesh.
struct RasterLookup {
  int width = 0, height = 0;
  std::vector<double> h;                          // mapped height of every pixel centre, row-major, NaN for nodata
  double u0 = 0, v0 = 0;                          // mapped position of the centre of pixel (0, 0)
  double colU = 0, colV = 0, rowU = 0, rowV = 0;  // inverse of the geotransform's 2x2 part

  std::optional<double> operator()(double u, double v) const {
    const double du = u - u0, dv = v - v0;  // small numbers first: keeps the pixel position exact
    const double col = colU * du + colV * dv, row = rowU * du + rowV * dv;
    if (!(col >= 0 && row >= 0 && col <= width - 1 && row <= height - 1)) return std::nullopt;
    const int c = std::min(static_cast<int>(col), width - 2);
    const int r = std::min(static_cast<int>(row), height - 2);
    const double fx = col - c, fy = row - r;
    const std::size_t tl = static_cast<std::size_t>(r) * width + c;
    const double zTL = h[tl], zTR = h[tl + 1], zBL = h[tl + width], zBR = h[tl + width + 1];
    // Below the diagonal (fy > fx): triangle (TL, BL, BR); else (TL, BR, TR).
    const double z = fy > fx ? zTL + fy * (zBL - zTL) + fx * (zBR - zBL) : zTL + fx * (zTR - zTL) + fy * (zBR - zTR);
    if (std::isnan(z)) return std::nullopt;
    return z;
  }
};

using Baseline = std::variant<HeightfieldLookup, RasterLookup>;

// Brute force: every triangle of the mesh, mapped once, tested in turn (the cost QOTA avoids).
struct MappedTriangle {
  double u[3], v[3], h[3];
};

std::vector<MappedTriangle> mapTriangles(const qota::Mesh& mesh, const qota::CartesianMapping& mapping) {
  std::vector<MappedTriangle> out;
  out.reserve(mesh.polygonCount());
  for (std::size_t p = 0; p < mesh.polygonCount(); ++p) {
    const auto corners = mesh.polygon(p);
    for (std::size_t k = 1; k + 1 < corners.size(); ++k) {  // a fan, as the index does
      MappedTriangle t{};
      const std::uint32_t idx[3] = {corners[0], corners[k], corners[k + 1]};
      for (int c = 0; c < 3; ++c) {
        const Eigen::Vector3d m = mapping.toMapped(mesh.vertices[idx[c]]);
        t.u[c] = m.x();
        t.v[c] = m.y();
        t.h[c] = m.z();
      }
      out.push_back(t);
    }
  }
  return out;
}

// The highest triangle over (u, v): closed triangles of either winding, height by barycentric
// weights (the signed areas of the point with each edge).
std::optional<double> bruteTop(const std::vector<MappedTriangle>& tris, double u, double v) {
  double best = -kInf;
  bool found = false;
  for (const MappedTriangle& t : tris) {
    const double w0 = (t.u[1] - u) * (t.v[2] - v) - (t.v[1] - v) * (t.u[2] - u);
    const double w1 = (t.u[2] - u) * (t.v[0] - v) - (t.v[2] - v) * (t.u[0] - u);
    const double w2 = (t.u[0] - u) * (t.v[1] - v) - (t.v[0] - v) * (t.u[1] - u);
    const bool inside = (w0 >= 0 && w1 >= 0 && w2 >= 0) || (w0 <= 0 && w1 <= 0 && w2 <= 0);
    const double area = w0 + w1 + w2;
    if (!inside || area == 0) continue;
    const double h = (w0 * t.h[0] + w1 * t.h[1] + w2 * t.h[2]) / area;
    if (h > best) best = h;
    found = true;
  }
  if (!found) return std::nullopt;
  return best;
}

// ---------------------------------------------------------------------------------------------
// Query sets.

struct QuerySets {
  std::vector<Point> hit;    // uniform over the surface's box
  std::vector<Point> miss;   // around the box, never in it
  std::vector<Point> walk;   // a coherent path, as a vehicle following the terrain makes
  std::vector<Point> brute;  // the first few hit points: brute force is too slow for more
};

std::vector<Point> uniformPoints(const qota::Box2& box, std::size_t n, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(box.ulo, box.uhi), v(box.vlo, box.vhi);
  std::vector<Point> out(n);
  for (Point& p : out) p = {u(rng), v(rng)};
  return out;
}

// Points in the box grown by its own size on every side, outside the box itself: they exercise
// the "no terrain" answer, which should cost next to nothing.
std::vector<Point> missPoints(const qota::Box2& box, std::size_t n, std::mt19937_64& rng) {
  const double su = box.uhi - box.ulo, sv = box.vhi - box.vlo;
  std::uniform_real_distribution<double> u(box.ulo - su, box.uhi + su), v(box.vlo - sv, box.vhi + sv);
  std::vector<Point> out;
  out.reserve(n);
  while (out.size() < n) {
    const Point p{u(rng), v(rng)};
    if (!box.contains(p.u, p.v)) out.push_back(p);
  }
  return out;
}

// Mirrors x into [lo, hi]; true when it did (the heading must then be mirrored too).
bool reflect(double& x, double lo, double hi) {
  if (x < lo) {
    x = 2 * lo - x;
    return true;
  }
  if (x > hi) {
    x = 2 * hi - x;
    return true;
  }
  return false;
}

// Steps of `step` with a heading that drifts slowly, bouncing off the box's sides: successive
// queries land in the same or neighbouring leaves, the case caches and branch predictors like.
std::vector<Point> walkPoints(const qota::Box2& box, double step, std::size_t n, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> start(0, 2 * std::numbers::pi);
  std::normal_distribution<double> turn(0, 0.05);
  Point p{(box.ulo + box.uhi) / 2, (box.vlo + box.vhi) / 2};
  double heading = start(rng);
  std::vector<Point> out(n);
  for (Point& q : out) {
    q = p;
    heading += turn(rng);
    p.u += step * std::cos(heading);
    p.v += step * std::sin(heading);
    if (reflect(p.u, box.ulo, box.uhi)) heading = std::numbers::pi - heading;
    if (reflect(p.v, box.vlo, box.vhi)) heading = -heading;
  }
  return out;
}

QuerySets makeQueries(const qota::Box2& domain, double cell, std::size_t brutePoints, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  QuerySets q;
  q.hit = uniformPoints(domain, kQueryCount, rng);
  q.miss = missPoints(domain, kQueryCount, rng);
  q.walk = walkPoints(domain, 0.3 * cell, kQueryCount, rng);
  q.brute.assign(q.hit.begin(), q.hit.begin() + static_cast<std::ptrdiff_t>(brutePoints));
  return q;
}

// ---------------------------------------------------------------------------------------------
// Terrains.

// Everything the benchmarks of one terrain share. Registered lambdas hold a reference to it, so
// it lives behind a unique_ptr and never moves.
struct Terrain {
  std::string name;
  std::string baselineName;  // "grid" or "raster"
  qota::Mesh mesh;
  qota::CartesianMapping mapping;
  qota::Box2 domain;  // mapped box of the surface
  double cell = 1;    // grid spacing in the mapped frame
  double relief = 1;  // height range, the scale of the agreement check
  Baseline baseline;
  QuerySets queries;
  std::vector<MappedTriangle> bruteTriangles;
  std::unique_ptr<qota::CartesianIndex> index;
  int buildIterations = 1;
  double checksum = 0;  // sum of every answer, so no query can be optimised away

  // Query benchmarks need an index even when the build benchmark was filtered out.
  const qota::CartesianIndex& ensureIndex() {
    if (!index) index = std::make_unique<qota::CartesianIndex>(mesh, mapping);
    return *index;
  }
};

// How to load one terrain; the names are known before loading, so the filter can skip it.
struct Recipe {
  std::string name;
  std::string baselineName;
  std::function<std::unique_ptr<Terrain>()> load;
};

double reliefOf(const qota::Mesh& mesh, const qota::CartesianMapping& mapping) {
  double lo = kInf, hi = -kInf;
  for (const Eigen::Vector3d& p : mesh.vertices) {
    const double h = mapping.toMapped(p).z();
    if (std::isnan(h)) continue;  // nodata vertex
    lo = std::min(lo, h);
    hi = std::max(hi, h);
  }
  return hi > lo ? hi - lo : 1.0;
}

void finishTerrain(Terrain& t, std::size_t brutePoints, std::uint64_t seed) {
  t.relief = reliefOf(t.mesh, t.mapping);
  t.queries = makeQueries(t.domain, t.cell, brutePoints, seed);
  t.bruteTriangles = mapTriangles(t.mesh, t.mapping);
  // Several builds of the small terrain (a few ms each); the large ones take long enough for one
  // or two.
  const double triangles = static_cast<double>(t.bruteTriangles.size());
  t.buildIterations = static_cast<int>(std::clamp(3e6 / triangles, 1.0, 20.0));
}

// nx x ny vertices, cell 1, relief about a fifth of the extent (hilly, not spiky).
std::unique_ptr<Terrain> syntheticTerrain(const std::string& name, int nx, int ny, std::uint64_t seed,
                                          std::size_t brutePoints) {
  const double cell = 1.0;
  const double extent = (std::max(nx, ny) - 1) * cell;
  qota::Heightfield field = qota::fractalHeightfield(nx, ny, cell, 0.2 * extent, seed);
  auto t = std::make_unique<Terrain>();
  t->name = name;
  t->baselineName = "grid";
  t->mesh = field.toMesh();
  t->domain = {field.x0, field.y0, field.x0 + (nx - 1) * cell, field.y0 + (ny - 1) * cell};
  t->cell = cell;
  t->baseline = HeightfieldLookup{std::move(field)};
  finishTerrain(*t, brutePoints, seed);
  return t;
}

RasterLookup rasterLookup(const qota::DemTerrain& dem) {
  const auto& g = dem.geotransform;
  const Eigen::Vector3d& origin = dem.mapping.origin();
  RasterLookup r;
  r.width = dem.width;
  r.height = dem.height;
  r.h.resize(dem.mesh.vertices.size());
  for (std::size_t i = 0; i < r.h.size(); ++i) r.h[i] = dem.mesh.vertices[i].z() - origin.z();
  const auto c0 = dem.pixelCentre(0, 0);
  r.u0 = c0[0] - origin.x();
  r.v0 = c0[1] - origin.y();
  // (du, dv) = [g1 g2; g4 g5] (dcol, drow), inverted.
  const double det = g[1] * g[5] - g[2] * g[4];
  r.colU = g[5] / det;
  r.colV = -g[2] / det;
  r.rowU = -g[4] / det;
  r.rowV = g[1] / det;
  return r;
}

// The mapped box of the pixel centres (the surface spans them, not the raster's outer border).
qota::Box2 rasterDomain(const qota::DemTerrain& dem) {
  qota::Box2 box{kInf, kInf, -kInf, -kInf};
  const double cols[2] = {0, dem.width - 1.0}, rows[2] = {0, dem.height - 1.0};
  for (double c : cols) {
    for (double r : rows) {
      const auto w = dem.pixelCentre(c, r);
      const Eigen::Vector3d m = dem.mapping.toMapped({w[0], w[1], 0});
      box = {std::min(box.ulo, m.x()), std::min(box.vlo, m.y()), std::max(box.uhi, m.x()), std::max(box.vhi, m.y())};
    }
  }
  return box;
}

std::unique_ptr<Terrain> demTerrain(const std::string& name, const std::string& path, std::uint64_t seed,
                                    std::size_t brutePoints) {
  qota::DemTerrain dem = qota::loadDem(path, {.lonLatAsCartesian = true});  // heights only
  // The raster baseline works in the mapped frame as a pure translation of the world.
  if (!dem.mapping.vertical()) throw std::runtime_error(path + ": mapping is not vertical");
  auto t = std::make_unique<Terrain>();
  t->name = name;
  t->baselineName = "raster";
  t->domain = rasterDomain(dem);
  const auto& g = dem.geotransform;
  t->cell = std::min(std::hypot(g[1], g[4]), std::hypot(g[2], g[5]));
  t->baseline = rasterLookup(dem);
  t->mapping = dem.mapping;
  t->mesh = std::move(dem.mesh);
  finishTerrain(*t, brutePoints, seed);
  return t;
}

std::vector<Recipe> recipes(bool quick) {
  std::vector<Recipe> out;
  out.push_back({"synth13k", "grid", [] { return syntheticTerrain("synth13k", 83, 82, 13, 200); }});
  if (quick) return out;
  out.push_back({"synth1M", "grid", [] { return syntheticTerrain("synth1M", 709, 709, 1001, 20); }});
  out.push_back({"rainier", "raster",
                 [] { return demTerrain("rainier", std::string(QOTA_DATA_DIR) + "/mt_rainier_90m.tif", 4392, 20); }});
  return out;
}

// ---------------------------------------------------------------------------------------------
// Benchmarks.

// One query per iteration, cycling through the points. Each query returns the number it adds to
// the checksum, having passed its full result through DoNotOptimize.
template <class Query>
void runQueries(benchmark::State& state, const std::vector<Point>& points, Query query, double& checksum) {
  const std::size_t n = points.size();
  std::size_t i = 0;
  double sum = 0;
  for (auto _ : state) {
    sum += query(points[i].u, points[i].v);
    if (++i == n) i = 0;
  }
  benchmark::DoNotOptimize(sum);
  checksum += sum;
  state.SetItemsProcessed(state.iterations());
}

double heightOrZero(std::optional<double> h) {
  benchmark::DoNotOptimize(h);
  return h.value_or(0.0);
}

void benchBuild(benchmark::State& state, Terrain& t) {
  for (auto _ : state) {
    auto index = std::make_unique<qota::CartesianIndex>(t.mesh, t.mapping);
    state.PauseTiming();
    t.index = std::move(index);  // frees the previous build outside the timing
    state.ResumeTiming();
  }
  const qota::IndexStats& s = t.index->stats();
  state.counters["B/tri"] = static_cast<double>(s.memoryBytes) / static_cast<double>(s.triangles);
}

void benchHeightBelow(benchmark::State& state, Terrain& t, const std::vector<Point>& points) {
  const qota::CartesianIndex& index = t.ensureIndex();
  runQueries(
      state, points, [&index](double u, double v) { return heightOrZero(index.heightBelow(u, v, kInf)); }, t.checksum);
}

// heightsBelow over blocks of points: one iteration is one point, and every kBatch-th iteration
// answers the next block, so the time per iteration is the amortised time per point.
constexpr std::size_t kBatch = 1024;

std::vector<qota::Point2> toPoint2(const std::vector<Point>& points) {
  std::vector<qota::Point2> out(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) out[i] = {points[i].u, points[i].v};
  return out;
}

void benchBatch(benchmark::State& state, Terrain& t, const std::vector<Point>& points) {
  const qota::CartesianIndex& index = t.ensureIndex();
  const std::vector<qota::Point2> p2 = toPoint2(points);
  std::vector<std::optional<double>> out(kBatch);
  const std::size_t n = p2.size();  // a multiple of kBatch
  std::size_t i = 0;
  double sum = 0;
  for (auto _ : state) {
    if (i % kBatch == 0) {
      index.heightsBelow(std::span(p2).subspan(i % n, kBatch), kInf, out);
      sum += out[0].value_or(0.0) + out[kBatch - 1].value_or(0.0);
    }
    ++i;
  }
  benchmark::DoNotOptimize(sum);
  t.checksum += sum;
  state.SetItemsProcessed(state.iterations());
}

void benchTop(benchmark::State& state, Terrain& t, const std::vector<Point>& points) {
  const qota::CartesianIndex& index = t.ensureIndex();
  runQueries(
      state, points,
      [&index](double u, double v) {
        std::optional<qota::Hit> hit = index.top(u, v);
        benchmark::DoNotOptimize(hit);
        return hit ? hit->height + hit->normal.z() : 0.0;
      },
      t.checksum);
}

void benchBaseline(benchmark::State& state, Terrain& t, const std::vector<Point>& points) {
  // Dispatch once, outside the timed loop, so the loop calls the lookup directly.
  std::visit(
      [&](const auto& lookup) {
        runQueries(
            state, points, [&lookup](double u, double v) { return heightOrZero(lookup(u, v)); }, t.checksum);
      },
      t.baseline);
}

void benchBrute(benchmark::State& state, Terrain& t) {
  const auto& tris = t.bruteTriangles;
  runQueries(
      state, t.queries.brute, [&tris](double u, double v) { return heightOrZero(bruteTop(tris, u, v)); }, t.checksum);
}

// Benchmark names are "<terrain>/<query set>/<method>", so --benchmark_filter can pick by any part.
std::vector<std::string> benchmarkNames(const std::string& terrain, const std::string& baseline) {
  std::vector<std::string> names{terrain + "/build"};
  for (const char* set : {"hit", "miss", "walk"}) {
    names.push_back(terrain + "/" + set + "/qota");
    names.push_back(terrain + "/" + set + "/qota_batch");
    if (std::string(set) == "hit") names.push_back(terrain + "/hit/qota_top");
    names.push_back(terrain + "/" + set + "/" + baseline);
  }
  names.push_back(terrain + "/hit/brute");
  return names;
}

void registerBenchmarks(Terrain& t) {
  using benchmark::RegisterBenchmark;
  const std::string& n = t.name;
  RegisterBenchmark((n + "/build").c_str(), [&t](benchmark::State& s) { benchBuild(s, t); })
      ->Iterations(t.buildIterations)
      ->Unit(benchmark::kMillisecond);
  const std::pair<const char*, const std::vector<Point>*> sets[] = {
      {"hit", &t.queries.hit}, {"miss", &t.queries.miss}, {"walk", &t.queries.walk}};
  for (const auto& [set, points] : sets) {
    const std::string prefix = n + "/" + set + "/";
    RegisterBenchmark((prefix + "qota").c_str(),
                      [&t, points](benchmark::State& s) { benchHeightBelow(s, t, *points); });
    RegisterBenchmark((prefix + "qota_batch").c_str(),
                      [&t, points](benchmark::State& s) { benchBatch(s, t, *points); });
    if (std::string(set) == "hit") {
      RegisterBenchmark((prefix + "qota_top").c_str(), [&t, points](benchmark::State& s) { benchTop(s, t, *points); });
    }
    RegisterBenchmark((prefix + t.baselineName).c_str(),
                      [&t, points](benchmark::State& s) { benchBaseline(s, t, *points); });
  }
  RegisterBenchmark((n + "/hit/brute").c_str(), [&t](benchmark::State& s) {
    benchBrute(s, t);
  })->Unit(benchmark::kMicrosecond);
}

// Whether Google Benchmark's filter would run any of these names (its rules: POSIX extended
// regex searched in the name, a leading '-' negates, "" and "all" mean everything). Used only to
// skip loading a terrain none of whose benchmarks would run.
bool filterSelectsAny(const std::string& filter, const std::vector<std::string>& names) {
  const bool negate = !filter.empty() && filter[0] == '-';
  const std::string rest = negate ? filter.substr(1) : filter;
  const std::string pattern = rest.empty() || rest == "all" ? std::string(1, '.') : rest;
  try {
    const std::regex re(pattern, std::regex::extended);
    return std::any_of(names.begin(), names.end(),
                       [&](const std::string& s) { return std::regex_search(s, re) != negate; });
  } catch (const std::regex_error&) {
    return true;  // let Google Benchmark report the bad filter
  }
}

// ---------------------------------------------------------------------------------------------
// Reporting.

// The console output as usual, plus every run's real time per iteration in seconds, by benchmark
// name. With repetitions, the mean replaces the single runs.
class CollectingReporter : public benchmark::ConsoleReporter {
 public:
  explicit CollectingReporter(OutputOptions options) : ConsoleReporter(options) {}

  // Called once per terrain: print the machine description only the first time, and keep one
  // name width so the terrains' tables line up.
  bool ReportContext(const Context& context) override {
    if (!contextPrinted_) {
      contextPrinted_ = true;
      ConsoleReporter::ReportContext(context);
    }
    name_field_width_ = std::max<std::size_t>({name_field_width_, context.name_field_width, 40});
    return true;
  }

  void ReportRuns(const std::vector<Run>& runs) override {
    ConsoleReporter::ReportRuns(runs);
    for (const Run& r : runs) {
      if (r.error_occurred) continue;
      const std::string& name = r.run_name.function_name;
      const bool mean = r.run_type == Run::RT_Aggregate && r.aggregate_name == "mean";
      if (r.run_type == Run::RT_Aggregate && !mean) continue;
      if (!mean && fromMean_.count(name)) continue;
      seconds_[name] = r.GetAdjustedRealTime() / benchmark::GetTimeUnitMultiplier(r.time_unit);
      if (mean) fromMean_[name] = true;
    }
  }

  std::optional<double> seconds(const std::string& name) const {
    const auto it = seconds_.find(name);
    if (it == seconds_.end()) return std::nullopt;
    return it->second;
  }

 private:
  bool contextPrinted_ = false;
  std::map<std::string, double> seconds_;
  std::map<std::string, bool> fromMean_;
};

// How two height functions agree over a point set.
struct Agreement {
  double maxAbs = 0;                 // over points where both have terrain
  std::size_t presenceMismatch = 0;  // one has terrain and the other not
};

template <class A, class B>
Agreement compare(const std::vector<Point>& points, A a, B b) {
  Agreement g;
  for (const Point& p : points) {
    const std::optional<double> ha = a(p.u, p.v), hb = b(p.u, p.v);
    if (ha.has_value() != hb.has_value()) {
      ++g.presenceMismatch;
    } else if (ha) {
      g.maxAbs = std::max(g.maxAbs, std::abs(*ha - *hb));
    }
  }
  return g;
}

// The same for answers already computed, one per point (the batch queries).
template <class B>
Agreement compareAnswers(const std::vector<Point>& points, const std::vector<std::optional<double>>& answers, B b) {
  std::size_t i = 0;
  return compare(
      points, [&](double, double) { return answers[i++]; }, b);
}

// One line of the final table: a query set timed with qota and with a baseline.
struct Row {
  std::string query;
  std::string qotaBench;
  std::string baselineName;
  std::string baselineBench;
  Agreement agreement;
};

struct TerrainReport {
  std::string name;
  qota::IndexStats stats;
  std::string buildBench;
  double relief = 1;
  double checksum = 0;
  std::vector<Row> rows;
};

// Checks qota against the baselines on the very points the benchmarks used (untimed).
TerrainReport makeReport(Terrain& t) {
  const qota::CartesianIndex& index = t.ensureIndex();
  const auto qotaHeight = [&index](double u, double v) { return index.heightBelow(u, v, kInf); };
  const auto qotaTopHeight = [&index](double u, double v) -> std::optional<double> {
    const auto hit = index.top(u, v);
    if (!hit) return std::nullopt;
    return hit->height;
  };
  const auto base = [&t](double u, double v) {
    return std::visit([&](const auto& lookup) { return lookup(u, v); }, t.baseline);
  };
  // The batch answers, computed once per set (untimed), compared point by point.
  const auto batchOf = [&index](const std::vector<Point>& points) {
    std::vector<std::optional<double>> out(points.size());
    index.heightsBelow(toPoint2(points), kInf, out);
    return out;
  };
  const auto hitBatch = batchOf(t.queries.hit), walkBatch = batchOf(t.queries.walk),
             missBatch = batchOf(t.queries.miss);
  const auto brute = [&t](double u, double v) { return bruteTop(t.bruteTriangles, u, v); };

  TerrainReport r;
  r.name = t.name;
  r.stats = index.stats();
  r.buildBench = t.name + "/build";
  r.relief = t.relief;
  r.checksum = t.checksum;
  const std::string p = t.name + "/", b = t.baselineName;
  r.rows.push_back({"hit", p + "hit/qota", b, p + "hit/" + b, compare(t.queries.hit, qotaHeight, base)});
  r.rows.push_back({"hit top()", p + "hit/qota_top", b, p + "hit/" + b, compare(t.queries.hit, qotaTopHeight, base)});
  r.rows.push_back(
      {"hit batch", p + "hit/qota_batch", b, p + "hit/" + b, compareAnswers(t.queries.hit, hitBatch, base)});
  r.rows.push_back({"miss", p + "miss/qota", b, p + "miss/" + b, compare(t.queries.miss, qotaHeight, base)});
  r.rows.push_back(
      {"miss batch", p + "miss/qota_batch", b, p + "miss/" + b, compareAnswers(t.queries.miss, missBatch, base)});
  r.rows.push_back({"walk", p + "walk/qota", b, p + "walk/" + b, compare(t.queries.walk, qotaHeight, base)});
  r.rows.push_back(
      {"walk batch", p + "walk/qota_batch", b, p + "walk/" + b, compareAnswers(t.queries.walk, walkBatch, base)});
  r.rows.push_back({"hit", p + "hit/qota", "brute", p + "hit/brute", compare(t.queries.brute, qotaHeight, brute)});
  return r;
}

std::string formatOr(std::optional<double> x, const char* format, const char* missing = "-") {
  if (!x) return missing;
  char buf[64];
  std::snprintf(buf, sizeof buf, format, *x);
  return buf;
}

std::optional<double> scaled(std::optional<double> x, double factor) {
  if (!x) return std::nullopt;
  return *x * factor;
}

void printTerrainTable(const std::vector<TerrainReport>& reports, const CollectingReporter& times) {
  std::printf("\n%-9s %10s %9s %7s %9s %9s %5s %9s\n", "terrain", "triangles", "build s", "B/tri", "nodes", "leaves",
              "depth", "avg tests");
  for (const TerrainReport& r : reports) {
    const auto& s = r.stats;
    std::printf("%-9s %10llu %9s %7.1f %9llu %9llu %5u %9.2f\n", r.name.c_str(),
                static_cast<unsigned long long>(s.triangles), formatOr(times.seconds(r.buildBench), "%.4f").c_str(),
                static_cast<double>(s.memoryBytes) / static_cast<double>(s.triangles),
                static_cast<unsigned long long>(s.tree.nodes), static_cast<unsigned long long>(s.tree.leaves),
                s.tree.depth, s.tree.averageTests);
  }
}

void printQueryTable(const std::vector<TerrainReport>& reports, const CollectingReporter& times) {
  std::printf(
      "\nns per query; speedup = baseline ns / qota ns (> 1: qota is faster);\n"
      "max|dh| = largest |qota - baseline| height on the timed points; "
      "1-sided = points where only one of them found terrain\n");
  std::printf("%-9s %-10s %10s %-8s %12s %9s %9s %7s %9s %6s\n", "terrain", "query", "qota ns", "baseline",
              "baseline ns", "speedup", "max|dh|", "1-sided", "build s", "B/tri");
  for (const TerrainReport& r : reports) {
    const double bytesPerTri = static_cast<double>(r.stats.memoryBytes) / static_cast<double>(r.stats.triangles);
    for (const Row& row : r.rows) {
      const auto q = scaled(times.seconds(row.qotaBench), 1e9);
      const auto b = scaled(times.seconds(row.baselineBench), 1e9);
      const std::optional<double> speedup = q && b ? std::optional(*b / *q) : std::nullopt;
      std::printf("%-9s %-10s %10s %-8s %12s %9s %9.2e %7zu %9s %6.1f\n", r.name.c_str(), row.query.c_str(),
                  formatOr(q, "%.1f").c_str(), row.baselineName.c_str(), formatOr(b, "%.1f").c_str(),
                  formatOr(speedup, "%.2f").c_str(), row.agreement.maxAbs, row.agreement.presenceMismatch,
                  formatOr(times.seconds(r.buildBench), "%.4f").c_str(), bytesPerTri);
    }
  }
}

// Warning lines for every row where qota and its baseline disagree; true when there were any.
bool printDisagreements(const std::vector<TerrainReport>& reports) {
  bool any = false;
  for (const TerrainReport& r : reports) {
    for (const Row& row : r.rows) {
      const Agreement& g = row.agreement;
      if (g.maxAbs <= kRelativeTolerance * r.relief && g.presenceMismatch == 0) continue;
      any = true;
      std::printf(
          "WARNING: %s %s: qota and %s disagree: max |dh| = %.3g (relief %.4g), "
          "%zu points with terrain in only one of them\n",
          r.name.c_str(), row.query.c_str(), row.baselineName.c_str(), g.maxAbs, r.relief, g.presenceMismatch);
    }
  }
  return any;
}

void printSummary(const std::vector<TerrainReport>& reports, const CollectingReporter& times) {
  std::printf("\n==== qota_bench summary ====\n");
  printTerrainTable(reports, times);
  printQueryTable(reports, times);
  std::printf("\n");
  if (!printDisagreements(reports)) {
    std::printf("qota heights agree with every baseline (within %.0e of the relief).\n", kRelativeTolerance);
  }
  for (const TerrainReport& r : reports) {
    std::printf("checksum %s: %.17g\n", r.name.c_str(), r.checksum);
  }
}

// Our own flags, removed before Google Benchmark parses the rest.
struct Options {
  bool quick = false;
  std::vector<std::string> benchmarkArgs;  // argv[0], the default min time, the user's flags
};

Options parseOptions(int argc, char** argv) {
  Options o;
  o.benchmarkArgs.push_back(argc > 0 ? argv[0] : "qota_bench");
  o.benchmarkArgs.push_back(kDefaultMinTime);
  for (int i = 1; i < argc; ++i) {
    if (std::string(argv[i]) == "--quick") {
      o.quick = true;
    } else {
      o.benchmarkArgs.push_back(argv[i]);
    }
  }
  return o;
}

}  // namespace

int main(int argc, char** argv) {
  Options options = parseOptions(argc, argv);
  std::vector<char*> args;
  for (std::string& a : options.benchmarkArgs) args.push_back(a.data());
  int benchArgc = static_cast<int>(args.size());
  args.push_back(nullptr);
  benchmark::Initialize(&benchArgc, args.data());
  if (benchmark::ReportUnrecognizedArguments(benchArgc, args.data())) return 1;

  CollectingReporter reporter(isatty(STDOUT_FILENO) ? benchmark::ConsoleReporter::OO_Defaults
                                                    : benchmark::ConsoleReporter::OO_Tabular);
  const std::string filter = benchmark::GetBenchmarkFilter();
  std::vector<TerrainReport> reports;
  int status = 0;
  // One terrain at a time: load, run its benchmarks, check it, free it.
  for (const Recipe& recipe : recipes(options.quick)) {
    if (!filterSelectsAny(filter, benchmarkNames(recipe.name, recipe.baselineName))) continue;
    try {
      std::unique_ptr<Terrain> terrain = recipe.load();
      registerBenchmarks(*terrain);
      benchmark::RunSpecifiedBenchmarks(&reporter);
      benchmark::ClearRegisteredBenchmarks();
      reports.push_back(makeReport(*terrain));
    } catch (const std::exception& e) {
      benchmark::ClearRegisteredBenchmarks();
      std::fprintf(stderr, "qota_bench: %s: %s\n", recipe.name.c_str(), e.what());
      status = 1;
    }
  }
  std::fflush(stderr);
  printSummary(reports, reporter);
  benchmark::Shutdown();
  return status;
}
