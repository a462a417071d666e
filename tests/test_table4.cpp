// The paper's Table 4 in spirit: a terrain of about 13,346 triangles indexed with the paper's
// four (Maxpoly, Maxdepth) settings. Fewer polygons per leaf must mean fewer tests per query.
#include <gtest/gtest.h>

#include <cstdio>

#include "qota/synthetic.hpp"
#include "qota/terrain.hpp"

TEST(Table4, AverageTestsFallWithMaxpoly) {
  // 83 x 82 vertices: 82 x 81 cells, 13,284 triangles (the paper's terrain had 13,346 polygons).
  const qota::Mesh mesh = qota::fractalHeightfield(83, 82, 10.0, 150.0, 1996).toMesh();
  struct Row {
    std::uint32_t maxPoly, maxDepth;
  };
  const Row rows[] = {{400, 5}, {16, 12}, {12, 12}, {8, 14}};
  std::printf("%-8s %-8s %10s %10s %10s %14s\n", "Maxpoly", "Maxdepth", "triangles", "nodes", "MB",
              "average tests");
  double previous = 1e300;
  for (const Row& r : rows) {
    const qota::TerrainIndex index(mesh, qota::CartesianMapping(), {{r.maxPoly, r.maxDepth}});
    const auto& s = index.stats();
    std::printf("%-8u %-8u %10llu %10llu %10.3f %14.2f\n", r.maxPoly, r.maxDepth,
                static_cast<unsigned long long>(s.triangles),
                static_cast<unsigned long long>(s.tree.nodes), s.memoryBytes / 1e6, s.tree.averageTests);
    EXPECT_LT(s.tree.averageTests, previous);
    EXPECT_LE(s.tree.maxLeafItems, std::max<std::uint32_t>(r.maxPoly, 6));
    previous = s.tree.averageTests;
  }
}
