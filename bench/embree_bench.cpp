// embree_bench: qota against Embree 3, the general ray-tracing engine, on exactly the same
// triangles and exactly the same vertical rays, measured in one run, single-threaded.
//
// Terrains: fractal heightfields of about 13k, 1M and 8M triangles (2048 x 2048 cells) and the
// bundled SRTM tile of Mount Rainier (2.85M), all in qota's mapped frame (Embree gets the same
// vertices as floats). Queries, 1M each: random points on the terrain (hits), random points off
// it (misses), and a coherent walk (small steps along rows). qota answers with heightBelow (one
// query at a time) and heightsBelow (batched); Embree with rtcIntersect1 (one ray at a time) and
// rtcIntersect16 (packets of 16). Every hit is compared (heights within float tolerance); direct
// indexing of the height grid is the physical limit for a DEM. Build times are single-threaded
// (Embree device "threads=1"); memory per triangle is what each keeps (Embree's through its
// memory monitor).
//
// Flags: --quick (the 13k terrain only, 100k queries).
#include <embree3/rtcore.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <optional>
#include <random>
#include <span>
#include <string>
#include <vector>

#include "embree_rays.hpp"
#include "qota/dem.hpp"
#include "qota/synthetic.hpp"
#include "qota/terrain.hpp"

namespace {

using Clock = std::chrono::steady_clock;
double seconds(Clock::time_point a, Clock::time_point b) { return std::chrono::duration<double>(b - a).count(); }

std::atomic<std::int64_t> embreeBytes{0};
bool monitor(void*, ssize_t bytes, bool) {
  embreeBytes += bytes;
  return true;
}

struct Terrain {
  std::string name;
  qota::Mesh mesh;  // world frame
  qota::CartesianMapping mapping;
  std::optional<qota::Heightfield> grid;  // the direct-indexing baseline, when there is one
};

struct Embree {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  double buildSeconds = 0;
  std::int64_t bytes = 0, bufferBytes = 0;
  ~Embree() {
    if (scene) rtcReleaseScene(scene);
    if (device) rtcReleaseDevice(device);
  }
};

// The same triangles as the index: every polygon fanned, vertices in the mapped frame (the
// index's own numbers), as floats.
void buildEmbree(Embree& e, const Terrain& t) {
  embreeBytes = 0;
  const auto t0 = Clock::now();
  e.device = rtcNewDevice("threads=1");
  rtcSetDeviceMemoryMonitorFunction(e.device, monitor, nullptr);
  e.scene = rtcNewScene(e.device);
  RTCGeometry geom = rtcNewGeometry(e.device, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                        3 * sizeof(float), t.mesh.vertices.size()));
  for (std::size_t i = 0; i < t.mesh.vertices.size(); ++i) {
    const Eigen::Vector3d m = t.mapping.toMapped(t.mesh.vertices[i]);
    v[3 * i] = static_cast<float>(m.x()), v[3 * i + 1] = static_cast<float>(m.y());
    v[3 * i + 2] = static_cast<float>(m.z());
  }
  std::size_t triangles = 0;
  for (std::size_t p = 0; p < t.mesh.polygonCount(); ++p) triangles += t.mesh.polygon(p).size() - 2;
  auto* idx = static_cast<unsigned*>(
      rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), triangles));
  std::size_t k = 0;
  for (std::size_t p = 0; p < t.mesh.polygonCount(); ++p) {
    const auto c = t.mesh.polygon(p);
    for (std::size_t j = 1; j + 1 < c.size(); ++j) {
      idx[3 * k] = c[0], idx[3 * k + 1] = c[j], idx[3 * k + 2] = c[j + 1];
      ++k;
    }
  }
  e.bufferBytes = embreeBytes.load();
  rtcCommitGeometry(geom);
  rtcAttachGeometry(e.scene, geom);
  rtcReleaseGeometry(geom);
  rtcSetSceneBuildQuality(e.scene, RTC_BUILD_QUALITY_MEDIUM);
  rtcCommitScene(e.scene);
  e.buildSeconds = seconds(t0, Clock::now());
  e.bytes = embreeBytes.load();  // everything the device allocated: buffers and the BVH
}

struct Query {
  double u, v;
};

struct Timing {
  double ns = 0;
  std::vector<float> heights;  // NaN for none
};

template <class F>
Timing timeQueries(const std::vector<Query>& q, F&& f) {
  Timing t;
  t.heights.resize(q.size());
  const auto t0 = Clock::now();
  for (std::size_t i = 0; i < q.size(); ++i) t.heights[i] = f(q[i].u, q[i].v);
  t.ns = seconds(t0, Clock::now()) * 1e9 / static_cast<double>(q.size());
  return t;
}

float embreeOne(const Embree& e, double u, double v, float top) { return bench::rayDown(e.scene, u, v, top); }

Timing embree16(const Embree& e, const std::vector<Query>& q, float top) {
  Timing t;
  t.heights.resize(q.size());
  const auto t0 = Clock::now();
  bench::raysDown16(
      e.scene, q.size(), [&](std::size_t i) { return q[i].u; }, [&](std::size_t i) { return q[i].v; },
      [&](std::size_t) { return top; }, [&](std::size_t i, float h) { t.heights[i] = h; });
  t.ns = seconds(t0, Clock::now()) * 1e9 / static_cast<double>(q.size());
  return t;
}

// Hits where both answered, compared; answered by one only (Embree is not watertight on edges
// in float) counted apart.
struct Agreement {
  std::size_t compared = 0, differ = 0, onlyOne = 0;
  double worst = 0;
};
Agreement agree(const Timing& a, const Timing& b, double tolerance) {
  Agreement g;
  for (std::size_t i = 0; i < a.heights.size(); ++i) {
    const bool ha = !std::isnan(a.heights[i]), hb = !std::isnan(b.heights[i]);
    if (ha != hb) {
      ++g.onlyOne;
      continue;
    }
    if (!ha) continue;
    ++g.compared;
    const double d = std::fabs(double(a.heights[i]) - double(b.heights[i]));
    g.worst = std::max(g.worst, d);
    g.differ += d > tolerance;
  }
  return g;
}

void run(const Terrain& t, std::size_t n) {
  // qota.
  const auto q0 = Clock::now();
  qota::IndexOptions oneThread;
  oneThread.buildThreads = 1;  // (the build's time is one thread's, as Embree's)
  const qota::CartesianIndex index(t.mesh, t.mapping, oneThread);
  const double qotaBuild = seconds(q0, Clock::now());
  const double bytesNow = static_cast<double>(index.memoryBytesNow());  // before anything builds the tree
  Embree e;
  buildEmbree(e, t);
  const qota::Box2 box = index.stats().domain;
  double hmax = -INFINITY, hmin = INFINITY;
  for (const auto& v : t.mesh.vertices) {
    if (std::isfinite(v.z())) hmax = std::max(hmax, v.z()), hmin = std::min(hmin, v.z());
  }
  const float top = static_cast<float>(t.mapping.toMapped({0, 0, hmax}).z() + 1.0);
  const double tolerance = 1e-5 * (std::fabs(hmax) + std::fabs(hmin) + 1);  // float heights

  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> unit(0, 1);
  const double su = box.uhi - box.ulo, sv = box.vhi - box.vlo;
  std::vector<Query> hit(n), miss(n), walk(n);
  for (auto& p : hit) p = {box.ulo + su * unit(rng), box.vlo + sv * unit(rng)};
  for (auto& p : miss) p = {box.uhi + su * (0.1 + unit(rng)), box.vlo + sv * unit(rng)};
  // Steps of 1/4096 of the terrain (half a cell at 8M), started off the cell lines, so that the
  // walk is not all on cell edges (where both sides take the exact predicate; see the README).
  const double step = su / 4096.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double along = std::fmod((static_cast<double>(i) + 0.37) * step, su);
    const double row = std::fmod(std::floor(static_cast<double>(i) * step / su) * sv / 97.0 + 0.37 * sv, sv);
    walk[i] = {box.ulo + along, box.vlo + row};
  }
  auto qotaOne = [&](double u, double v) {
    const auto h = index.heightBelow(u, v, INFINITY);
    return h ? static_cast<float>(*h) : NAN;
  };
  double parallelNs = 0;
  bool parallelSame = false;
  auto qotaBatch = [&](const std::vector<Query>& q) {
    std::vector<qota::Point2> p(q.size());
    for (std::size_t i = 0; i < q.size(); ++i) p[i] = {q[i].u, q[i].v};
    std::vector<std::optional<double>> out(q.size());
    Timing t2;
    const auto b0 = Clock::now();
    for (std::size_t i = 0; i < p.size(); i += 4096) {
      const std::size_t k = std::min<std::size_t>(4096, p.size() - i);
      index.heightsBelow(std::span(p.data() + i, k), INFINITY, std::span(out.data() + i, k));
    }
    t2.ns = seconds(b0, Clock::now()) * 1e9 / static_cast<double>(p.size());
    // Both cores: the same batches on two threads.
    std::vector<std::optional<double>> out2(q.size());
    const auto p0 = Clock::now();
    for (std::size_t i = 0; i < p.size(); i += 65536) {
      const std::size_t k = std::min<std::size_t>(65536, p.size() - i);
      index.heightsBelowParallel(std::span(p.data() + i, k), INFINITY, std::span(out2.data() + i, k), 2);
    }
    parallelNs = seconds(p0, Clock::now()) * 1e9 / static_cast<double>(p.size());
    parallelSame = out2 == out;
    t2.heights.resize(q.size());
    for (std::size_t i = 0; i < q.size(); ++i) t2.heights[i] = out[i] ? static_cast<float>(*out[i]) : NAN;
    return t2;
  };
  auto embreeOneF = [&](double u, double v) { return embreeOne(e, u, v, top); };

  const Timing qh = timeQueries(hit, qotaOne), qhb = qotaBatch(hit), eh = timeQueries(hit, embreeOneF),
               eh16 = embree16(e, hit, top);
  const Timing qm = timeQueries(miss, qotaOne), em = timeQueries(miss, embreeOneF);
  const Timing qw = timeQueries(walk, qotaOne), ew = timeQueries(walk, embreeOneF);
  // The same walk through a cursor, qota's way of following a moving object (temporal coherence).
  qota::Cursor cursor;
  const Timing qwc = timeQueries(walk, [&](double u, double v) {
    const auto h = index.heightBelow(cursor, u, v, INFINITY);
    return h ? static_cast<float>(*h) : NAN;
  });
  std::optional<Timing> gh, gw;
  // The general path on the same terrain: the quadtree alone, as for any mesh that is not a grid.
  std::optional<Timing> qt;
  double quadtreeBytes = 0;
  if (index.gridFastPath()) {
    qota::IndexOptions o;
    o.gridFastPath = false;
    const qota::CartesianIndex general(t.mesh, t.mapping, o);
    quadtreeBytes = static_cast<double>(general.memoryBytesNow());
    qt = timeQueries(hit, [&](double u, double v) {
      const auto h = general.heightBelow(u, v, INFINITY);
      return h ? static_cast<float>(*h) : NAN;
    });
  }
  if (t.grid) {
    auto g = [&](double u, double v) {
      double h = 0;
      return t.grid->heightAt(u, v, h) ? static_cast<float>(h) : NAN;
    };
    gh = timeQueries(hit, g);
    gw = timeQueries(walk, g);
  }
  const Agreement a = agree(qh, eh, tolerance), a16 = agree(qh, eh16, tolerance), ab = agree(qh, qhb, 0),
                  aw = agree(qw, ew, tolerance);
  const double tris = static_cast<double>(index.stats().triangles);
  std::printf("\n%s: %.0f triangles\n", t.name.c_str(), tris);
  std::printf("  build (1 thread):    qota %.3f s   embree %.3f s   (qota/embree %.2f)\n", qotaBuild, e.buildSeconds,
              qotaBuild / e.buildSeconds);
  const double queryBytes = bytesNow / tris;
  std::printf(
      "  bytes per triangle:  qota %.0f (%.0f with its quadtree)   embree %.0f (of which its vertex and index buffers: "
      "%.0f)\n",
      queryBytes, static_cast<double>(index.stats().memoryBytes) / tris, static_cast<double>(e.bytes) / tris,
      static_cast<double>(e.bufferBytes) / tris);
  std::printf("  %-22s %9s %9s %9s %12s %9s\n", "ns/query", "qota", "embree", "ratio", "qota batch", "embree16");
  std::printf("  %-22s %9.1f %9.1f %8.1fx %12.1f %9.1f\n", "random hit", qh.ns, eh.ns, eh.ns / qh.ns, qhb.ns, eh16.ns);
  std::printf("  %-22s %9.1f %9.1f %8.1fx\n", "random miss", qm.ns, em.ns, em.ns / qm.ns);
  std::printf("  %-22s %9.1f %9.1f %8.1fx\n", "coherent walk", qw.ns, ew.ns, ew.ns / qw.ns);
  std::printf("  %-22s %9.1f %9.1f %8.1fx   (same heights: %s)\n", "walk with a cursor", qwc.ns, ew.ns, ew.ns / qwc.ns,
              agree(qw, qwc, 0).differ == 0 && agree(qw, qwc, 0).onlyOne == 0 ? "yes" : "NO");
  std::printf("  %-22s %9.1f ns random hit, 2 threads (same answers: %s)\n", "qota batched, both cores", parallelNs,
              parallelSame ? "yes" : "NO");
  if (qt) {
    std::printf("  %-22s %9.1f ns random hit (%.1fx embree), %.0f bytes per triangle (identical heights: %s)\n",
                "qota quadtree only", qt->ns, eh.ns / qt->ns, quadtreeBytes / tris,
                agree(qh, *qt, 0).differ == 0 && agree(qh, *qt, 0).onlyOne == 0 ? "yes" : "NO");
  }
  if (gh) {
    std::printf("  %-22s %9.1f (hit)  %9.1f (walk): qota/grid %.1fx hit, %.1fx walk, %.1fx walk with a cursor\n",
                "direct grid indexing", gh->ns, gw->ns, qh.ns / gh->ns, qw.ns / gw->ns, qwc.ns / gw->ns);
  }
  std::printf(
      "  agreement: %zu hits compared, %zu differ by more than %.2g (worst %.2g), %zu answered "
      "by one side only; rtcIntersect16: %zu differ, %zu one side; walk: %zu differ, %zu one "
      "side; batch = single: %s\n",
      a.compared, a.differ, tolerance, a.worst, a.onlyOne, a16.differ, a16.onlyOne, aw.differ, aw.onlyOne,
      ab.differ == 0 && ab.onlyOne == 0 ? "yes" : "NO");
}

Terrain fractal(int side, const char* name) {
  Terrain t{name, {}, qota::CartesianMapping(), qota::fractalHeightfield(side, side, 1.0, side * 0.05, 7)};
  // Heights in float, as a Float32 raster stores them: then Embree's float vertices are exactly
  // qota's, and both answer on the same triangles.
  for (double& z : t.grid->z) z = static_cast<float>(z);
  t.mesh = t.grid->toMesh();
  return t;
}

}  // namespace

int main(int argc, char** argv) {
  bool quick = false;
  for (int i = 1; i < argc; ++i) quick = quick || !std::strcmp(argv[i], "--quick");
  const std::size_t n = quick ? 100000 : 1000000;
  std::printf("embree_bench: qota vs Embree %d.%d.%d, %zu queries per set, one thread\n", RTC_VERSION_MAJOR,
              RTC_VERSION_MINOR, RTC_VERSION_PATCH, n);
  run(fractal(82, "fractal 13k"), n);
  if (quick) return 0;
  run(fractal(708, "fractal 1M"), n);
  run(fractal(2049, "fractal 8M (2048 x 2048 cells)"), n);
  const qota::DemTerrain dem = qota::loadDem(QOTA_DATA_DIR "/mt_rainier_90m.tif", {.lonLatAsCartesian = true});
  run(Terrain{"SRTM Rainier", dem.mesh, dem.mapping, std::nullopt}, n);
  return 0;
}
