// The paper's Table 4 in spirit: a terrain of about 13,346 triangles indexed with the paper's
// four (Maxpoly, Maxdepth) settings. Fewer polygons per leaf must mean fewer tests per query.
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstdio>
#include <variant>

#include <random>

#include "qota/mesh_io.hpp"
#include "qota/treefile.hpp"
#include "qota/synthetic.hpp"
#include "qota/terrain.hpp"

TEST(Table4, AverageTestsFallWithMaxpoly) {
  // 83 x 82 vertices: 82 x 81 cells, 13,284 triangles (the paper's terrain had 13,346 polygons).
  const qota::Mesh mesh = qota::fractalHeightfield(83, 82, 10.0, 150.0, 1996).toMesh();
  struct Row {
    std::uint32_t maxPoly, maxDepth;
  };
  const Row rows[] = {{400, 5}, {16, 12}, {12, 12}, {8, 14}};
  std::printf("%-8s %-8s %10s %10s %10s %14s\n", "Maxpoly", "Maxdepth", "triangles", "nodes", "MB", "average tests");
  double previous = 1e300;
  for (const Row& r : rows) {
    const qota::CartesianIndex index(mesh, qota::CartesianMapping(), {{r.maxPoly, r.maxDepth}});
    const auto& s = index.stats();
    std::printf("%-8u %-8u %10llu %10llu %10.3f %14.2f\n", r.maxPoly, r.maxDepth,
                static_cast<unsigned long long>(s.triangles), static_cast<unsigned long long>(s.tree.nodes),
                s.memoryBytes / 1e6, s.tree.averageTests);
    EXPECT_LT(s.tree.averageTests, previous);
    EXPECT_LE(s.tree.maxLeafItems, std::max<std::uint32_t>(r.maxPoly, 6));
    previous = s.tree.averageTests;
  }
}

// The cost-model cuts (QuadtreeOptions::Cuts::CostModel) shape a different tree with the same
// answers: on an irregular mesh (the Delft city block) at random points, and on a grid also
// exactly at vertices and edge midpoints, plain and through a cursor.
TEST(Table4, CostModelCutsAnswerAsMidpointCuts) {
  const qota::MeshFile city = qota::loadMeshFile(QOTA_DATA_DIR "/testarea.obj");
  const qota::Mesh grid = qota::fractalHeightfield(83, 82, 10.0, 150.0, 1996).toMesh();
  const std::pair<const qota::Mesh*, qota::CartesianMapping> cases[] = {
      {&city.mesh, qota::CartesianMapping({0, 0, -1}, city.origin)}, {&grid, qota::CartesianMapping()}};
  for (const auto& [mesh, mapping] : cases) {
    qota::IndexOptions mid, cost;
    mid.gridFastPath = cost.gridFastPath = false;
    cost.tree.cuts = qota::QuadtreeOptions::Cuts::CostModel;
    const qota::CartesianIndex a(*mesh, mapping, mid), b(*mesh, mapping, cost);
    ASSERT_FALSE(a.tree().storedCuts());
    ASSERT_TRUE(b.tree().storedCuts());
    std::printf("midpoint: %llu nodes, %.2f tests; cost model: %llu nodes, %.2f tests\n",
                static_cast<unsigned long long>(a.stats().tree.nodes), a.stats().tree.averageTests,
                static_cast<unsigned long long>(b.stats().tree.nodes), b.stats().tree.averageTests);
    const qota::Box2 box = a.stats().domain;
    std::mt19937_64 rng(4);
    std::uniform_real_distribution<double> unit(0, 1);
    std::vector<qota::Point2> points;
    for (int i = 0; i < 50000; ++i) {
      points.push_back({box.ulo + (box.uhi - box.ulo) * unit(rng), box.vlo + (box.vhi - box.vlo) * unit(rng)});
    }
    // Exactly at vertices and edges only on the continuous grid: on the city block a point exactly
    // on the edge of a step (a roof edge over the ground's, under a wall) has two heights, and a
    // single-layer leaf may answer the lower one (a known limit, see the README).
    for (std::size_t p = 0; mesh == &grid && p < mesh->polygonCount(); p += 3) {
      const auto idx = mesh->polygon(p);
      const Eigen::Vector3d u = mapping.toMapped(mesh->vertices[idx[0]]), v = mapping.toMapped(mesh->vertices[idx[1]]);
      points.push_back({u.x(), u.y()});
      points.push_back({0.5 * (u.x() + v.x()), 0.5 * (u.y() + v.y())});
    }
    qota::Cursor cursor;
    for (const qota::Point2& p : points) {
      const auto x = a.below(p.u, p.v, 1e300), y = b.below(p.u, p.v, 1e300), z = b.below(cursor, p.u, p.v, 1e300);
      ASSERT_EQ(x.has_value(), y.has_value()) << p.u << " " << p.v;
      ASSERT_EQ(y.has_value(), z.has_value());
      if (x) {
        // At a vertex or edge shared by several triangles their planes give the same height to
        // within rounding, and which of them answers depends on the leaf (a single-layer leaf
        // takes the smallest id, a stacked one the highest of the rounded heights): equal to
        // within rounding there, identical elsewhere.
        const double tolerance = 1e-12 * (1 + std::fabs(x->height));
        ASSERT_NEAR(x->height, y->height, tolerance) << p.u << " " << p.v;
        ASSERT_NEAR(y->height, z->height, tolerance);
        if (std::fabs(x->height - y->height) == 0) {
          // (Same height: same polygon, unless several hold the point at that height.)
          ASSERT_EQ(a.below(p.u, p.v, x->height)->height, b.below(p.u, p.v, x->height)->height);
        }
      }
    }
    // A batch descends the stored cuts in steps (Quadtree::stepWalk): the single queries'
    // answers, bit for bit.
    std::vector<std::optional<double>> batch(points.size());
    b.heightsBelow(points, 1e300, batch);
    for (std::size_t i = 0; i < points.size(); ++i) {
      const auto one = b.heightBelow(points[i].u, points[i].v, 1e300);
      ASSERT_EQ(batch[i].has_value(), one.has_value()) << points[i].u << " " << points[i].v;
      if (one) {
        ASSERT_EQ(std::bit_cast<std::uint64_t>(*batch[i]), std::bit_cast<std::uint64_t>(*one));
      }
    }
    // The cuts go into tree files and come back.
    const std::string path = ::testing::TempDir() + "/cost_model_cuts.qota";
    qota::saveTree(path, b);
    const qota::TreeFile file = qota::loadTree(path);
    const auto& c = std::get<qota::CartesianIndex>(file.index);
    ASSERT_TRUE(c.tree().storedCuts());
    for (std::size_t i = 0; i < points.size(); i += 7) {
      ASSERT_EQ(c.heightBelow(points[i].u, points[i].v, 1e300), b.heightBelow(points[i].u, points[i].v, 1e300));
    }
    std::remove(path.c_str());
  }
}
