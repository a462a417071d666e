// tin_bench: qota against Embree 3 on irregular terrains (the meshes the paper was written for),
// every answer checked against an exact oracle in the same run, and each query set set beside
// the machine's latency of one dependent DRAM miss, measured here.
//
// Terrains: Delaunay TINs (CGAL, here only) of random points over a fractal terrain, about 1M and
// 4M triangles; a TIN of 700,000 random pixel centres of the bundled SRTM Rainier tile; the Delft
// city mesh (3dfier, data/testarea.obj: ground, roads, water and buildings with their walls),
// centred so that Embree's floats hold it. Queries, 1M a set, one thread:
//   random: the highest surface at random points (heightBelow(u, v, +inf); rtcIntersect1 from above);
//   below:  the nearest surface below a start just above or just below the top surface (heightBelow
//           from z; a ray from z down), as a vehicle or a falling object asks;
//   batches of both (heightsBelow over 4096 points; rtcIntersect16 packets);
//   a coherent walk (small steps), plain and through a cursor.
// The oracle: a uniform bucket grid of the triangles with CGAL's exact orientation test (closed
// triangles), the plane of the winning triangle's corners in double; every qota answer of every
// set must match it (a hit where it hits, within 1e-9 of the terrain's size, none where it has
// none), else the run fails. Embree's answers (float) are compared for the record.
//
// The latency: a pointer chase over a 256 MiB random cycle (huge pages asked for), ns per step:
// what one dependent cache miss costs a query on a terrain larger than the cache. Beside it, a
// model of a random query's dependent loads and the misses they make (printMissModel: this
// machine's hardware counters are not available to perf).
//
// Flags: --quick (a 16k-triangle TIN and Delft, 100k queries; ctest runs it), --large (adds the
// 4M TIN, the default does too; --no-large leaves it out), --only tin|tin4m|rainier|delft (that
// terrain alone), --maxpoly N (qota's Maxpoly, default the library's 8: the trade of bytes and
// build time against batch speed, docs/performance.md).
#include <embree3/rtcore.h>
#include <sys/mman.h>

#include <CGAL/Delaunay_triangulation_2.h>
#include <Eigen/Geometry>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <numeric>
#include <optional>
#include <random>
#include <span>
#include <string>
#include <thread>
#include <vector>

#include "embree_rays.hpp"
#include "qota/dem.hpp"
#include "qota/mesh_io.hpp"
#include "qota/synthetic.hpp"
#include "qota/terrain.hpp"

namespace {

using Clock = std::chrono::steady_clock;
double seconds(Clock::time_point a, Clock::time_point b) { return std::chrono::duration<double>(b - a).count(); }
constexpr double kInf = std::numeric_limits<double>::infinity();

// ---- the machine: one dependent DRAM miss ------------------------------------------------------

// ns per load of `chains` pointer chases through one random cycle over kBytes (huge pages asked
// for), started evenly apart and stepped together: one chain's loads each wait for the last (a
// dependent miss); several chains' loads of a step are independent and overlap.
double chaseNs(std::size_t kBytes, std::size_t kSteps, std::size_t chains = 1) {
  constexpr std::size_t kMaxChains = 16;
  chains = std::clamp<std::size_t>(chains, 1, kMaxChains);
  const std::size_t kN = kBytes / sizeof(std::uint64_t);
  void* raw = std::aligned_alloc(std::size_t{2} << 20, kBytes);
  if (!raw) return NAN;
  madvise(raw, kBytes, MADV_HUGEPAGE);
  auto* next = static_cast<std::uint64_t*>(raw);
  // Sattolo's shuffle: one cycle through every slot, in random order.
  std::vector<std::uint32_t> order(kN);
  std::iota(order.begin(), order.end(), 0u);
  std::mt19937_64 rng(3);
  for (std::size_t i = kN - 1; i > 0; --i) std::swap(order[i], order[rng() % i]);
  for (std::size_t i = 0; i < kN; ++i) next[order[i]] = order[(i + 1) % kN];
  std::uint64_t at[kMaxChains];
  for (std::size_t c = 0; c < chains; ++c) at[c] = order[c * (kN / chains)];
  const auto step = [&] {
    for (std::size_t c = 0; c < chains; ++c) at[c] = next[at[c]];
  };
  for (std::size_t i = 0; i < kSteps / 10; ++i) step();  // warm the page tables
  const auto t0 = Clock::now();
  for (std::size_t i = 0; i < kSteps; ++i) step();
  const double ns = seconds(t0, Clock::now()) * 1e9 / static_cast<double>(kSteps * chains);
  std::uint64_t keep = 0;
  for (std::size_t c = 0; c < chains; ++c) keep ^= at[c];
  if (keep == ~std::uint64_t{0}) std::printf("-");  // keep the chases
  std::free(raw);
  return ns;
}

double dramLatencyNs() { return chaseNs(std::size_t{256} << 20, 20'000'000); }

// ns per miss when 16 are in flight at once (16 chases over 256 MiB): what a batch that overlaps
// its queries' misses can reach at best, the core's few line-fill buffers, not the latency,
// then bounding it.
double overlappedMissNs() { return chaseNs(std::size_t{256} << 20, 2'000'000, 16); }

// The cache a query's arrays can use, as this machine shows it (the sizes the system reports
// can be a host's, not this machine's share): the largest power-of-two chase, from 1 MiB, that
// still costs less than half a DRAM miss a step.
double effectiveCacheBytes(double dramNs) {
  double cached = 0;
  for (std::size_t mib = 1; mib <= 128; mib *= 2) {
    if (chaseNs(mib << 20, 2'000'000) >= 0.5 * dramNs) break;
    cached = static_cast<double>(mib << 20);
  }
  return cached;
}

// ---- terrains ----------------------------------------------------------------------------------

struct Terrain {
  std::string name;
  qota::Mesh mesh;  // world = mapped frame (vertical gravity, origin 0)
};

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Vb = CGAL::Triangulation_vertex_base_with_info_2<std::uint32_t, K>;
using Tds = CGAL::Triangulation_data_structure_2<Vb>;
using Delaunay = CGAL::Delaunay_triangulation_2<K, Tds>;

// The Delaunay triangulation of the points' (x, y), heights carried along.
qota::Mesh delaunay(const std::vector<Eigen::Vector3d>& points) {
  std::vector<std::pair<K::Point_2, std::uint32_t>> in(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    in[i] = {K::Point_2(points[i].x(), points[i].y()), static_cast<std::uint32_t>(i)};
  }
  Delaunay dt(in.begin(), in.end());
  qota::Mesh mesh;
  mesh.vertices = points;
  mesh.indices.reserve(3 * dt.number_of_faces());
  for (auto f = dt.finite_faces_begin(); f != dt.finite_faces_end(); ++f) {
    mesh.addTriangle(f->vertex(0)->info(), f->vertex(1)->info(), f->vertex(2)->info());
  }
  return mesh;
}

Terrain fractalTin(std::size_t points, const char* name) {
  // Random points over a 2048-cell fractal terrain, heights from its surface (in float, as a
  // Float32 raster would give them, so that Embree's float vertices are qota's).
  const int side = 2049;
  const qota::Heightfield f = qota::fractalHeightfield(side, side, 1.0, side * 0.05, 7);
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> at(0.0, side - 1.0);
  std::vector<Eigen::Vector3d> p;
  p.reserve(points);
  while (p.size() < points) {
    const double x = at(rng), y = at(rng);
    double h = 0;
    if (f.heightAt(x, y, h)) p.emplace_back(x, y, static_cast<float>(h));
  }
  return {name, delaunay(p)};
}

Terrain rainierTin(std::size_t points) {
  const qota::DemTerrain dem = qota::loadDem(QOTA_DATA_DIR "/mt_rainier_90m.tif", {.lonLatAsCartesian = true});
  std::vector<std::uint32_t> pick(dem.mesh.vertices.size());
  std::iota(pick.begin(), pick.end(), 0u);
  std::mt19937_64 rng(5);
  std::shuffle(pick.begin(), pick.end(), rng);
  std::vector<Eigen::Vector3d> p;
  // Degrees east and north scaled to metres at the tile's latitude, heights in metres: a TIN as
  // a GIS would make it.
  const double m = 111320.0, mx = m * std::cos(46.85 * M_PI / 180);
  for (std::uint32_t i : pick) {
    const Eigen::Vector3d& v = dem.mesh.vertices[i];
    if (!std::isfinite(v.z())) continue;
    p.emplace_back((v.x() + 121.75) * mx, (v.y() - 46.85) * m, v.z());
    if (p.size() == points) break;
  }
  return {"SRTM Rainier TIN (" + std::to_string(points) + " random pixel centres)", delaunay(p)};
}

Terrain delft() {
  qota::MeshFile f = qota::loadMeshFile(QOTA_DATA_DIR "/testarea.obj");
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(kInf), hi = -lo;
  for (const auto& v : f.mesh.vertices) lo = lo.cwiseMin(v), hi = hi.cwiseMax(v);
  const Eigen::Vector3d c(std::round(0.5 * (lo.x() + hi.x())), std::round(0.5 * (lo.y() + hi.y())), 0);
  for (auto& v : f.mesh.vertices) v -= c;  // exact: metres with millimetres, round centre
  return {"Delft city mesh (3dfier)", std::move(f.mesh)};
}

// Every polygon fanned from its first corner, as the index fans it.
std::vector<std::array<std::uint32_t, 3>> trianglesOf(const qota::Mesh& mesh) {
  std::vector<std::array<std::uint32_t, 3>> t;
  t.reserve(mesh.indices.size() / 3);
  for (std::size_t p = 0; p < mesh.polygonCount(); ++p) {
    const auto c = mesh.polygon(p);
    for (std::size_t j = 1; j + 1 < c.size(); ++j) t.push_back({c[0], c[j], c[j + 1]});
  }
  return t;
}

// ---- the oracle --------------------------------------------------------------------------------

// A uniform grid of buckets, each listing the triangles whose box meets it; a point's answer
// from its bucket's triangles: closed containment by CGAL's exact orientation, the height on the
// plane of the corners (in double), clamped to their range.
class Oracle {
 public:
  Oracle(const qota::Mesh& mesh, const std::vector<std::array<std::uint32_t, 3>>& tris) : mesh_(mesh), tris_(tris) {
    lo_ = {kInf, kInf}, hi_ = {-kInf, -kInf};
    for (const auto& v : mesh.vertices) {
      lo_[0] = std::min(lo_[0], v.x()), lo_[1] = std::min(lo_[1], v.y());
      hi_[0] = std::max(hi_[0], v.x()), hi_[1] = std::max(hi_[1], v.y());
    }
    const double area = (hi_[0] - lo_[0]) * (hi_[1] - lo_[1]);
    const double cell = std::sqrt(area / static_cast<double>(std::max<std::size_t>(1, tris.size())));
    nx_ = std::max(1, std::min(8192, static_cast<int>((hi_[0] - lo_[0]) / cell)));
    ny_ = std::max(1, std::min(8192, static_cast<int>((hi_[1] - lo_[1]) / cell)));
    std::vector<std::uint32_t> count(static_cast<std::size_t>(nx_) * ny_ + 1, 0);
    auto each = [&](std::size_t t, auto&& f) {
      double xl = kInf, yl = kInf, xh = -kInf, yh = -kInf;
      for (std::uint32_t i : tris_[t]) {
        const auto& v = mesh_.vertices[i];
        xl = std::min(xl, v.x()), yl = std::min(yl, v.y()), xh = std::max(xh, v.x()), yh = std::max(yh, v.y());
      }
      const int c0 = col(xl), c1 = col(xh), r0 = row(yl), r1 = row(yh);
      for (int r = r0; r <= r1; ++r) {
        for (int c = c0; c <= c1; ++c) f(static_cast<std::size_t>(r) * nx_ + c);
      }
    };
    for (std::size_t t = 0; t < tris.size(); ++t) each(t, [&](std::size_t b) { ++count[b + 1]; });
    std::partial_sum(count.begin(), count.end(), count.begin());
    start_ = count;
    items_.resize(count.back());
    for (std::size_t t = 0; t < tris.size(); ++t) {
      each(t, [&](std::size_t b) { items_[count[b]++] = static_cast<std::uint32_t>(t); });
    }
  }

  // The highest surface at (x, y) with height <= z; tol: how far a double evaluation of it may
  // be off (a near-vertical triangle's height is ill-conditioned: its range).
  std::optional<double> below(double x, double y, double z, double* tol = nullptr) const {
    if (!(x >= lo_[0] && x <= hi_[0] && y >= lo_[1] && y <= hi_[1])) return std::nullopt;
    const std::size_t b = static_cast<std::size_t>(row(y)) * nx_ + col(x);
    std::optional<double> best;
    double bestTol = 0;
    const K::Point_2 p(x, y);
    for (std::uint32_t k = start_[b]; k < start_[b + 1]; ++k) {
      const auto& t = tris_[items_[k]];
      const Eigen::Vector3d &a = mesh_.vertices[t[0]], &bb = mesh_.vertices[t[1]], &c = mesh_.vertices[t[2]];
      const K::Point_2 pa(a.x(), a.y()), pb(bb.x(), bb.y()), pc(c.x(), c.y());
      const CGAL::Orientation o = CGAL::orientation(pa, pb, pc);
      if (o == CGAL::COLLINEAR) continue;  // no area: holds no point of a vertical line but its edge
      const auto o0 = CGAL::orientation(pa, pb, p), o1 = CGAL::orientation(pb, pc, p),
                 o2 = CGAL::orientation(pc, pa, p);
      if ((o0 != o && o0 != CGAL::COLLINEAR) || (o1 != o && o1 != CGAL::COLLINEAR) ||
          (o2 != o && o2 != CGAL::COLLINEAR)) {
        continue;
      }
      const Eigen::Vector3d n = (bb - a).cross(c - a);
      double h = a.z() - (n.x() * (x - a.x()) + n.y() * (y - a.y())) / n.z();
      const double hl = std::min({a.z(), bb.z(), c.z()}), hh = std::max({a.z(), bb.z(), c.z()});
      h = std::clamp(h, hl, hh);
      if (h > z || (best && h <= *best)) continue;
      best = h;
      // Steep: a point's height moves by the slope times its rounding; give it the range.
      bestTol = std::fabs(n.z()) < 1e-6 * n.norm() ? hh - hl : 0.0;
    }
    if (tol) *tol = bestTol;
    return best;
  }

 private:
  int col(double x) const { return std::clamp(static_cast<int>((x - lo_[0]) / (hi_[0] - lo_[0]) * nx_), 0, nx_ - 1); }
  int row(double y) const { return std::clamp(static_cast<int>((y - lo_[1]) / (hi_[1] - lo_[1]) * ny_), 0, ny_ - 1); }
  const qota::Mesh& mesh_;
  const std::vector<std::array<std::uint32_t, 3>>& tris_;
  std::array<double, 2> lo_, hi_;
  int nx_ = 1, ny_ = 1;
  std::vector<std::uint32_t> start_, items_;
};

// ---- Embree ------------------------------------------------------------------------------------

std::atomic<std::int64_t> embreeBytes{0};
bool monitor(void*, ssize_t bytes, bool) {
  embreeBytes += bytes;
  return true;
}

struct Embree {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  double buildSeconds = 0;
  std::int64_t bytes = 0;
  Embree(const qota::Mesh& mesh, const std::vector<std::array<std::uint32_t, 3>>& tris) {
    embreeBytes = 0;
    const auto t0 = Clock::now();
    device = rtcNewDevice("threads=1");
    rtcSetDeviceMemoryMonitorFunction(device, monitor, nullptr);
    scene = rtcNewScene(device);
    RTCGeometry geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                          3 * sizeof(float), mesh.vertices.size()));
    for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
      for (int k = 0; k < 3; ++k) v[3 * i + k] = static_cast<float>(mesh.vertices[i][k]);
    }
    auto* idx = static_cast<unsigned*>(
        rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), tris.size()));
    for (std::size_t t = 0; t < tris.size(); ++t) {
      for (int k = 0; k < 3; ++k) idx[3 * t + k] = tris[t][k];
    }
    rtcCommitGeometry(geom);
    rtcAttachGeometry(scene, geom);
    rtcReleaseGeometry(geom);
    rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_MEDIUM);
    rtcCommitScene(scene);
    buildSeconds = seconds(t0, Clock::now());
    bytes = embreeBytes.load();
  }
  ~Embree() {
    rtcReleaseScene(scene);
    rtcReleaseDevice(device);
  }
  Embree(const Embree&) = delete;
  Embree& operator=(const Embree&) = delete;

  float one(double u, double v, float z) const { return bench::rayDown(scene, u, v, z); }
  // Packets of 16 rays down from zs[i].
  void sixteen(std::span<const qota::Point2> p, std::span<const float> zs, std::span<float> out) const {
    bench::raysDown16(
        scene, p.size(), [&](std::size_t i) { return p[i].u; }, [&](std::size_t i) { return p[i].v; },
        [&](std::size_t i) { return zs[i]; }, [&](std::size_t i, float h) { out[i] = h; });
  }
};

// ---- a query set -------------------------------------------------------------------------------

struct Set {
  std::string name;
  std::vector<qota::Point2> points;
  std::vector<double> zs;  // the line's start (+inf: from above)
};

template <class F>
double timed(F&& f, std::size_t n) {
  const auto t0 = Clock::now();
  f();
  return seconds(t0, Clock::now()) * 1e9 / static_cast<double>(n);
}

struct Check {
  std::size_t wrong = 0, hits = 0;
  std::string first;
};

// qota's answers against the oracle's: the same hit or none, heights within tol.
Check check(const Oracle& oracle, const Set& s, std::span<const std::optional<double>> got, double scale) {
  Check c;
  for (std::size_t i = 0; i < s.points.size(); ++i) {
    double tol = 0;
    const auto want = oracle.below(s.points[i].u, s.points[i].v, s.zs[i], &tol);
    tol += 1e-9 * scale;
    c.hits += want.has_value();
    const bool ok = want.has_value() == got[i].has_value() && (!want || std::fabs(*want - *got[i]) <= tol);
    if (ok) continue;
    if (c.wrong++ == 0) {
      char line[256];
      std::snprintf(line, sizeof line, "(%.17g, %.17g) from %.17g: qota %s, oracle %s", s.points[i].u, s.points[i].v,
                    s.zs[i], got[i] ? std::to_string(*got[i]).c_str() : "none",
                    want ? std::to_string(*want).c_str() : "none");
      c.first = line;
    }
  }
  return c;
}

// A model of a random query's dependent loads on the quadtree: the jump table's cell, the node
// levels below it (the leaves' depths weighted by their area), the leaf's references, then the
// triangles' records (fetched together). Each is a DRAM miss unless its array is cached; with
// the cache's size C (effectiveCacheBytes), an array of S bytes is counted a miss with
// probability 1 - C / S (as if it had the cache to itself: a lower bound on the misses).
void printMissModel(const qota::CartesianIndex& index, double measuredMisses, double cache, double overlappedNs,
                    double measuredBatchNs) {
  const qota::Quadtree& tree = index.tree();
  const std::uint32_t k = tree.jumpDepth();
  const auto nodes = tree.nodes();
  double below = 0;  // expected node levels read below the table
  double leafItems = 0;
  tree.forEachLeaf([&](const qota::Quadtree::Node& leaf, std::uint32_t depth) {
    const double share = std::ldexp(1.0, -2 * static_cast<int>(depth));
    below += share * (depth > k ? depth - k : 0);
    leafItems += share * qota::Quadtree::leafSize(leaf);
  });
  const double jumpBytes = k ? std::ldexp(8.0, 2 * static_cast<int>(k)) : 8.0;
  const double nodeBytes = 8.0 * static_cast<double>(nodes.size());
  const double refBytes = 4.0 * static_cast<double>(index.stats().tree.references);
  const double recordBytes = 64.0 * static_cast<double>(index.stats().triangles);  // one line each
  const auto miss = [&](double bytes) { return std::max(0.0, 1.0 - cache / bytes); };
  const double loads = 1 + below + 1 + 1;
  const double misses = miss(jumpBytes) + below * miss(nodeBytes) + miss(refBytes) + miss(recordBytes);
  const auto mib = [](double b) { return b / (1 << 20); };
  std::printf(
      "  model, a random query: jump cell (%.1f MiB) + %.2f node levels (%.1f MiB) + references (%.1f MiB) +"
      " %.1f records (%.0f MiB, together) = %.2f dependent loads, at least %.2f DRAM misses beyond a %.0f MiB"
      " cache; measured %.2f misses' time\n",
      mib(jumpBytes), below, mib(nodeBytes), mib(refBytes), leafItems, mib(recordBytes), loads, misses, mib(cache),
      measuredMisses);
  // A batch overlaps its queries' misses: it is then bound by the lines it reads a query (the
  // cell, the nodes below it, the references, a line a record), each at the machine's overlapped
  // miss time.
  const double lines = 1 + below + 1 + leafItems;
  if (misses > 0) {
    std::printf(
        "  model, a batch: %.1f lines a query x %.1f ns (a miss among 16 in flight) = %.0f ns; measured %.0f ns\n",
        lines, overlappedNs, lines * overlappedNs, measuredBatchNs);
  } else {
    std::printf("  model, a batch: its %.1f lines a query are all in the cache: no DRAM bound (measured %.0f ns)\n",
                lines, measuredBatchNs);
  }
  // Where the bytes go: the records (64 a triangle, one line), what the exact tests and the
  // answers need besides (each triangle's corners and polygon, the vertices), the tree.
  const double nt = static_cast<double>(index.stats().triangles);
  const double all = static_cast<double>(index.stats().memoryBytes);
  const double treeBytes = static_cast<double>(index.stats().tree.memoryBytes);
  std::printf(
      "  bytes a triangle: %.0f records + %.0f corners, polygons and vertices + %.0f tree (%.0f references,"
      " %.0f nodes and jump table)\n",
      recordBytes / nt, (all - treeBytes - recordBytes) / nt, treeBytes / nt, refBytes / nt,
      (treeBytes - refBytes) / nt);
}

bool run(const Terrain& t, std::size_t n, double latencyNs, double cacheBytes, double overlappedNs,
         std::uint32_t maxPoly) {
  const auto tris = trianglesOf(t.mesh);
  // Builds: the fastest of three each (a build's time varies by a tenth or more here), qota on
  // one thread as Embree, and on every core.
  double qotaBuild = kInf, qotaBuildAll = kInf, embreeBuild = kInf;
  std::optional<qota::CartesianIndex> built;
  qota::IndexOptions everyCore, oneThread;
  everyCore.tree.maxPoly = oneThread.tree.maxPoly = maxPoly;
  oneThread.buildThreads = 1;
  for (int round = 0; round < 3; ++round) {
    built.reset();
    auto q0 = Clock::now();
    built.emplace(t.mesh, qota::CartesianMapping(), everyCore);
    qotaBuildAll = std::min(qotaBuildAll, seconds(q0, Clock::now()));
    built.reset();
    q0 = Clock::now();
    built.emplace(t.mesh, qota::CartesianMapping(), oneThread);
    qotaBuild = std::min(qotaBuild, seconds(q0, Clock::now()));
    if (round < 2) embreeBuild = std::min(embreeBuild, Embree(t.mesh, tris).buildSeconds);
  }
  const qota::CartesianIndex& index = *built;
  const Embree e(t.mesh, tris);
  embreeBuild = std::min(embreeBuild, e.buildSeconds);
  const Oracle oracle(t.mesh, tris);
  const qota::Box2 box = index.stats().domain;
  double hlo = kInf, hhi = -kInf;
  for (const auto& v : t.mesh.vertices) hlo = std::min(hlo, v.z()), hhi = std::max(hhi, v.z());
  const double scale = std::max({box.uhi - box.ulo, box.vhi - box.vlo, hhi - hlo, 1.0}) +
                       std::max({std::fabs(box.ulo), std::fabs(box.uhi), std::fabs(hlo), std::fabs(hhi)});
  const double top = hhi + 1.0;

  // The query sets: random points over the terrain's box; the same points from just above or just
  // below the top surface there (by a thousandth of the height range, either way at random);
  // a walk of small steps along rows.
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> unit(0, 1);
  const double su = box.uhi - box.ulo, sv = box.vhi - box.vlo;
  Set random{"random", {}, {}}, below{"below", {}, {}}, walk{"coherent walk", {}, {}};
  random.points.resize(n), random.zs.assign(n, kInf);
  for (auto& p : random.points) p = {box.ulo + su * unit(rng), box.vlo + sv * unit(rng)};
  below.points = random.points, below.zs.resize(n);
  const double nudge = 1e-3 * (hhi - hlo + 1.0);
  for (std::size_t i = 0; i < n; ++i) {
    const auto h = oracle.below(below.points[i].u, below.points[i].v, kInf);
    below.zs[i] = h ? *h + (unit(rng) < 0.5 ? nudge : -nudge) : top;
  }
  walk.points.resize(n), walk.zs.assign(n, kInf);
  const double step = su / 4096.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double along = std::fmod((static_cast<double>(i) + 0.37) * step, su);
    const double row = std::fmod(std::floor(static_cast<double>(i) * step / su) * sv / 97.0 + 0.37 * sv, sv);
    walk.points[i] = {box.ulo + along, box.vlo + row};
  }

  std::printf("\n%s: %zu triangles\n", t.name.c_str(), tris.size());
  std::printf(
      "  build (1 thread):    qota %.3f s   embree %.3f s   (qota/embree %.2f; fastest of 3)"
      "   qota on %u threads %.3f s\n",
      qotaBuild, embreeBuild, qotaBuild / embreeBuild, std::max(1u, std::thread::hardware_concurrency()), qotaBuildAll);
  const double nt = static_cast<double>(tris.size());
  std::printf("  bytes per triangle:  qota %.0f   embree %.0f   (qota/embree %.2f)\n",
              static_cast<double>(index.stats().memoryBytes) / nt, static_cast<double>(e.bytes) / nt,
              static_cast<double>(index.stats().memoryBytes) / static_cast<double>(e.bytes));
  std::printf("  %-16s %9s %9s %8s %12s %9s %8s %11s  %s\n", "ns/query", "qota", "embree", "ratio", "qota batch",
              "embree16", "ratio", "qota/miss", "exact");
  bool ok = true;
  double randomMisses = 0, randomBatchNs = 0;
  for (const Set* s : {&random, &below, &walk}) {
    const std::size_t m = s->points.size();
    std::vector<std::optional<double>> single(m), batch(m);
    std::vector<float> ez(m), eh(m), e16(m);
    for (std::size_t i = 0; i < m; ++i)
      ez[i] = std::isinf(s->zs[i]) ? static_cast<float>(top) : static_cast<float>(s->zs[i]);
    const double qs = timed(
        [&] {
          for (std::size_t i = 0; i < m; ++i) single[i] = index.heightBelow(s->points[i].u, s->points[i].v, s->zs[i]);
        },
        m);
    const double es = timed(
        [&] {
          for (std::size_t i = 0; i < m; ++i) eh[i] = e.one(s->points[i].u, s->points[i].v, ez[i]);
        },
        m);
    const double qb = timed(
        [&] {
          for (std::size_t i = 0; i < m; i += 4096) {
            const std::size_t k = std::min<std::size_t>(4096, m - i);
            index.heightsBelow(std::span(s->points).subspan(i, k), std::span(s->zs).subspan(i, k),
                               std::span(batch).subspan(i, k));
          }
        },
        m);
    const double eb = timed([&] { e.sixteen(s->points, ez, e16); }, m);
    const Check cs = check(oracle, *s, single, scale);
    const bool same = single == batch;
    ok = ok && cs.wrong == 0 && same;
    std::printf(
        "  %-16s %9.1f %9.1f %7.2fx %12.1f %9.1f %7.2fx %10.2fx  %s\n", s->name.c_str(), qs, es, es / qs, qb, eb,
        eb / qb, qs / latencyNs,
        cs.wrong == 0 && same
            ? ("all " + std::to_string(m) + " (" + std::to_string(cs.hits) + " hits)").c_str()
            : ("WRONG: " + std::to_string(cs.wrong) + (same ? "" : ", batch differs") + "; first " + cs.first).c_str());
    if (s == &random) randomMisses = qs / latencyNs, randomBatchNs = qb;
    if (s == &walk) {
      qota::Cursor cursor;
      std::vector<std::optional<double>> viaCursor(m);
      const double qc = timed(
          [&] {
            for (std::size_t i = 0; i < m; ++i) {
              viaCursor[i] = index.heightBelow(cursor, s->points[i].u, s->points[i].v, s->zs[i]);
            }
          },
          m);
      const bool sameWalk = viaCursor == single;
      ok = ok && sameWalk;
      std::printf("  %-16s %9.1f %9.1f %7.2fx %12s %9s %8s %10.2fx  %s\n", "walk, cursor", qc, es, es / qc, "", "", "",
                  qc / latencyNs, sameWalk ? "= plain walk" : "DIFFERS from the plain walk");
    }
  }
  printMissModel(index, randomMisses, cacheBytes, overlappedNs, randomBatchNs);
  return ok;
}

}  // namespace

int main(int argc, char** argv) {
  bool quick = false, large = true;
  std::string only;  // one terrain: tin, tin4m, rainier or delft
  std::uint32_t maxPoly = qota::QuadtreeOptions{}.maxPoly;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--quick")) {
      quick = true;
    } else if (!std::strcmp(argv[i], "--no-large")) {
      large = false;
    } else if (!std::strcmp(argv[i], "--only") && i + 1 < argc &&
               std::strstr(" tin tin4m rainier delft ", (" " + std::string(argv[i + 1]) + " ").c_str())) {
      only = argv[++i];
    } else if (!std::strcmp(argv[i], "--maxpoly") && i + 1 < argc) {
      char* end = nullptr;
      const unsigned long v = std::strtoul(argv[++i], &end, 10);
      if (*end != '\0' || v < 1 || v > 64) {
        std::fprintf(stderr, "tin_bench: --maxpoly takes a whole number from 1 to 64, not '%s'\n", argv[i]);
        return 2;
      }
      maxPoly = static_cast<std::uint32_t>(v);
    } else if (std::strcmp(argv[i], "--large") != 0) {
      std::fprintf(
          stderr,
          "tin_bench: unknown option %s (--quick, --large, --no-large, --only tin|tin4m|rainier|delft, --maxpoly N)\n",
          argv[i]);
      return 2;
    }
  }
  const auto wanted = [&](const char* key) { return only.empty() || only == key; };
  const std::size_t n = quick ? 100000 : 1000000;
  const double latency = dramLatencyNs();
  std::printf("tin_bench: qota (Maxpoly %u) vs Embree %d.%d.%d on irregular meshes, %zu queries per set, one thread\n",
              maxPoly, RTC_VERSION_MAJOR, RTC_VERSION_MINOR, RTC_VERSION_PATCH, n);
  std::printf("one dependent DRAM miss (pointer chase over 256 MiB): %.1f ns; 'qota/miss' is a query's time in those\n",
              latency);
  const double cache = effectiveCacheBytes(latency);
  std::printf("cache a chase still finds (largest power of two under half a miss a step): %.0f MiB\n",
              cache / (1 << 20));
  const double overlapped = overlappedMissNs();
  std::printf(
      "a miss among 16 in flight (16 chases stepped together): %.1f ns, %.1fx the dependent miss's throughput\n",
      overlapped, latency / overlapped);
  bool ok = true;
  if (quick) {
    if (wanted("tin"))
      ok = run(fractalTin(8192, "Delaunay TIN over a fractal (8k points)"), n, latency, cache, overlapped, maxPoly) &&
           ok;
    if (wanted("delft")) ok = run(delft(), n, latency, cache, overlapped, maxPoly) && ok;
  } else {
    if (wanted("tin"))
      ok = run(fractalTin(524288, "Delaunay TIN over a fractal (524k points)"), n, latency, cache, overlapped,
               maxPoly) &&
           ok;
    if ((large && only.empty()) || only == "tin4m")
      ok = run(fractalTin(2097152, "Delaunay TIN over a fractal (2.1M points)"), n, latency, cache, overlapped,
               maxPoly) &&
           ok;
    if (wanted("rainier")) ok = run(rainierTin(700000), n, latency, cache, overlapped, maxPoly) && ok;
    if (wanted("delft")) ok = run(delft(), n, latency, cache, overlapped, maxPoly) && ok;
  }
  std::printf("\n%s\n", ok ? "every qota answer equals the exact oracle's" : "SOME qota ANSWERS ARE WRONG");
  return ok ? 0 : 1;
}
