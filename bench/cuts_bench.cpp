// cuts_bench: the quadtree's cut strategies side by side (QuadtreeOptions::cuts): the paper's
// midpoint cuts and the cost model, on the same terrains and the same random vertical queries,
// measured in one run. For each of the paper's Table 4 settings (Maxpoly, Maxdepth) it prints
// the tree's nodes, megabytes and average polygon tests per query (Table 4's metric: leaf size
// averaged over the domain's area), the ns per random query, and checks that both strategies
// give identical answers. The grid fast path is off: this is the quadtree every non-grid mesh
// uses. Flags: --quick (the small terrain only, fewer queries).
#include <chrono>
#include <cstdio>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "qota/dem.hpp"
#include "qota/mesh_io.hpp"
#include "qota/synthetic.hpp"
#include "qota/terrain.hpp"

namespace {

using Clock = std::chrono::steady_clock;
using Cuts = qota::QuadtreeOptions::Cuts;

struct Terrain {
  std::string name;
  qota::Mesh mesh;
  qota::CartesianMapping mapping;
};

struct Setting {
  std::uint32_t maxPoly, maxDepth;
};

void run(const Terrain& t, std::size_t queries, const std::vector<Setting>& settings) {
  std::printf("\n%s: %zu polygons\n", t.name.c_str(), t.mesh.polygonCount());
  std::printf("  %-8s %-8s %-9s %9s %8s %11s %9s %9s %s\n", "Maxpoly", "Maxdepth", "cuts", "nodes", "MB", "avg tests",
              "ns/query", "build s", "same answers");
  for (const Setting s : settings) {
    std::vector<std::optional<double>> reference;
    for (const Cuts cuts : {Cuts::Midpoint, Cuts::CostModel}) {
      qota::IndexOptions o;
      o.gridFastPath = false;
      o.tree = {s.maxPoly, s.maxDepth, cuts};
      const auto t0 = Clock::now();
      const qota::CartesianIndex index(t.mesh, t.mapping, o);
      const double build = std::chrono::duration<double>(Clock::now() - t0).count();
      const auto& st = index.stats();
      std::mt19937_64 rng(7);
      std::uniform_real_distribution<double> unit(0, 1);
      const qota::Box2 box = st.domain;
      std::vector<qota::Point2> points(queries);
      for (auto& p : points) p = {box.ulo + (box.uhi - box.ulo) * unit(rng), box.vlo + (box.vhi - box.vlo) * unit(rng)};
      std::vector<std::optional<double>> heights(queries);
      const auto t1 = Clock::now();
      for (std::size_t i = 0; i < queries; ++i) heights[i] = index.heightBelow(points[i].u, points[i].v, INFINITY);
      const double ns = std::chrono::duration<double>(Clock::now() - t1).count() * 1e9 / static_cast<double>(queries);
      if (reference.empty()) reference = heights;
      std::printf("  %-8u %-8u %-9s %9llu %8.2f %11.2f %9.1f %9.3f %s\n", s.maxPoly, s.maxDepth,
                  cuts == Cuts::Midpoint ? "midpoint" : "cost", static_cast<unsigned long long>(st.tree.nodes),
                  static_cast<double>(st.tree.memoryBytes) / 1e6, st.tree.averageTests, ns, build,
                  heights == reference ? "yes" : "NO");
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  bool quick = false;
  for (int i = 1; i < argc; ++i) quick = quick || !std::strcmp(argv[i], "--quick");
  const std::size_t n = quick ? 20000 : 1000000;
  std::printf("cuts_bench: midpoint cuts (the paper's) against the cost model, %zu random queries per row\n", n);
  // The paper's terrain size (about 13,346 polygons) with its four settings; larger terrains with
  // the default (Maxpoly 8, Maxdepth 16).
  const std::vector<Setting> table4{{400, 5}, {16, 12}, {12, 12}, {8, 14}}, standard{{8, 16}};
  run({"fractal 13k", qota::fractalHeightfield(83, 82, 10.0, 150.0, 1996).toMesh(), qota::CartesianMapping()}, n,
      table4);
  if (quick) return 0;
  // An irregular mesh: the Delft city block (buildings' roofs and walls, ground, water).
  const qota::MeshFile city = qota::loadMeshFile(QOTA_DATA_DIR "/testarea.obj");
  run({"Delft city block (OBJ)", city.mesh, qota::CartesianMapping({0, 0, -1}, city.origin)}, n, table4);
  run({"fractal 1M", qota::fractalHeightfield(708, 708, 1.0, 35.0, 7).toMesh(), qota::CartesianMapping()}, n, standard);
  const qota::DemTerrain dem = qota::loadDem(QOTA_DATA_DIR "/mt_rainier_90m.tif", {.lonLatAsCartesian = true});
  run({"SRTM Rainier", dem.mesh, dem.mapping}, n, standard);
  return 0;
}
