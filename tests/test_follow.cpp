// Terrain following: cursors (identical answers to plain queries, on cut lines too), poses from
// footprints, move validation and locale containment, in the Cartesian and curved mappings.
#include <gtest/gtest.h>

#include <random>

#include "qota/curved.hpp"
#include "qota/error.hpp"
#include "qota/follow.hpp"
#include "qota/glm_interop.hpp"
#include "qota/scene.hpp"
#include "qota/globe.hpp"
#include "qota/mesh_io.hpp"
#include "qota/synthetic.hpp"
#include "qota/terrain.hpp"
#include "random_terrain.hpp"

namespace {

using namespace qota;

double uniform(std::mt19937_64& rng, double lo, double hi) {
  return std::uniform_real_distribution<double>(lo, hi)(rng);
}

// A coherent walk (small random steps, sometimes a jump) plus points exactly on the cursor's box
// edges, where the boundary rule decides the leaf.
template <class Query, class Plain>
void expectCursorMatches(Box2 domain, Query&& withCursor, Plain&& plain, const Quadtree& tree, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  Cursor cursor;
  double u = 0.5 * (domain.ulo + domain.uhi), v = 0.5 * (domain.vlo + domain.vhi);
  const double step = 1e-3 * (domain.uhi - domain.ulo);
  for (int i = 0; i < 200000; ++i) {
    if (i % 5000 == 0) {
      u = uniform(rng, domain.ulo, domain.uhi), v = uniform(rng, domain.vlo, domain.vhi);
    } else if (i % 7 == 0 && cursor.box.uhi > cursor.box.ulo) {
      // Exactly on an edge of the last leaf's box.
      const int k = i % 4;
      u = k == 0 ? cursor.box.uhi : k == 1 ? cursor.box.ulo : u;
      v = k == 2 ? cursor.box.vhi : k == 3 ? cursor.box.vlo : v;
    } else {
      u = std::clamp(u + uniform(rng, -step, step), domain.ulo, domain.uhi);
      v = std::clamp(v + uniform(rng, -step, step), domain.vlo, domain.vhi);
    }
    ASSERT_EQ(withCursor(cursor, u, v), plain(u, v)) << i << " at " << u << " " << v;
    if (tree.contains(u, v)) {
      const Quadtree::Node a = tree.leafNode(u, v);
      Cursor fresh;
      const Quadtree::Node b = tree.leafNode(u, v, fresh);
      ASSERT_EQ(a.first, b.first);
      ASSERT_EQ(a.count, b.count);
    }
  }
}

std::optional<std::uint32_t> polygonOf(const std::optional<Hit>& h) {
  return h ? std::optional<std::uint32_t>(h->polygon) : std::nullopt;
}

TEST(Cursor, CartesianMatchesPlainQueries) {
  test::RandomTerrainSpec spec;
  spec.grid = 120;
  const Mesh mesh = test::randomTerrain(spec, 5);  // holes, overlapping plates, walls
  const CartesianIndex index(mesh, CartesianMapping());
  const Box2 d = index.stats().domain;
  expectCursorMatches(
      d, [&](Cursor& c, double u, double v) { return polygonOf(index.below(c, u, v, 5.0)); },
      [&](double u, double v) { return polygonOf(index.below(u, v, 5.0)); }, index.tree(), 1);
  expectCursorMatches(
      d, [&](Cursor& c, double u, double v) { return polygonOf(index.above(c, u, v, 0.0)); },
      [&](double u, double v) { return polygonOf(index.above(u, v, 0.0)); }, index.tree(), 2);
  expectCursorMatches(
      d, [&](Cursor& c, double u, double v) { return index.heightBelow(c, u, v, 1e9); },
      [&](double u, double v) { return index.heightBelow(u, v, 1e9); }, index.tree(), 3);
}

TEST(Cursor, CurvedMatchesPlainQueries) {
  const PlanetTerrain planet = loadPlanet(QOTA_DATA_DIR "/etopo20.tif");
  const SphericalIndex sphere(planet.dem.mesh, planet.mapping);
  expectCursorMatches(
      sphere.stats().domain, [&](Cursor& c, double u, double v) { return sphere.height(c, u, v); },
      [&](double u, double v) { return sphere.height(u, v); }, sphere.tree(), 4);
  const Mesh station = stationMesh(fractalHeightfield(200, 60, 1.0, 8.0, 3), {250, 1000});
  const CylindricalIndex tube(station, CylindricalMapping());
  expectCursorMatches(
      tube.stats().domain, [&](Cursor& c, double u, double v) { return polygonOf(tube.below(c, u, v, 100.0)); },
      [&](double u, double v) { return polygonOf(tube.below(u, v, 100.0)); }, tube.tree(), 5);
}

// A plane z = 0.2 x - 0.1 y + 3 as a triangulated grid, with a hole at cells (5..7, 5..7).
Mesh tiltedPlane(bool hole) {
  Heightfield f;
  f.nx = f.ny = 21;
  f.cell = 1.0;
  for (int j = 0; j < 21; ++j) {
    for (int i = 0; i < 21; ++i) f.z.push_back(0.2 * i - 0.1 * j + 3);
  }
  Mesh full = f.toMesh(), m;
  m.vertices = full.vertices;
  for (std::size_t p = 0; p < full.polygonCount(); ++p) {
    const int cell = static_cast<int>(p / 2), ci = cell % 20, cj = cell / 20;
    if (hole && ci >= 5 && ci <= 7 && cj >= 5 && cj <= 7) continue;
    m.addPolygon(full.polygon(p));
  }
  return m;
}

TEST(Pose, ThreeSamplesOnAPlane) {
  const Mesh mesh = tiltedPlane(false);
  const CartesianIndex index(mesh, CartesianMapping());
  const Eigen::Vector3d samples[3] = {{10, 10, 50}, {12, 10, 50}, {11, 12, 50}};
  const FootprintPose fp = poseFromFootprint(index, std::span(samples), Eigen::Vector3d(1, 0, 0));
  ASSERT_TRUE(fp.pose);
  EXPECT_TRUE(fp.missing.empty());
  const Eigen::Vector3d n = Eigen::Vector3d(-0.2, 0.1, 1).normalized();
  EXPECT_NEAR((fp.up - n).norm(), 0, 1e-12);
  EXPECT_NEAR((fp.pose->orientation.col(2) - n).norm(), 0, 1e-12);
  // Heading kept: x axis in the plane, in the vertical plane of the requested heading.
  EXPECT_NEAR(fp.pose->orientation.col(0).y(), 0, 1e-12);
  EXPECT_GT(fp.pose->orientation.col(0).x(), 0.9);
  EXPECT_NEAR(fp.pose->position.z(), 0.2 * 11 - 0.1 * 32.0 / 3 + 3, 1e-12);
  EXPECT_NEAR(fp.pose->orientation.determinant(), 1, 1e-12);
  const glm::dmat4 m = toGlm(*fp.pose);
  EXPECT_NEAR(m[3][2], fp.pose->position.z(), 0);
}

TEST(Pose, LeastSquaresAndMissingSamples) {
  const Mesh mesh = tiltedPlane(true);
  const CartesianIndex index(mesh, CartesianMapping());
  // Four wheels, one over the hole.
  const Eigen::Vector3d wheels[4] = {{3, 3, 99}, {6.5, 6.5, 99}, {3, 4, 99}, {4, 3, 99}};
  const FootprintPose fp = poseFromFootprint(index, std::span(wheels), Eigen::Vector3d(0, 1, 0));
  ASSERT_EQ(fp.missing, std::vector<std::size_t>{1});
  ASSERT_TRUE(fp.pose);
  EXPECT_NEAR((fp.up - Eigen::Vector3d(-0.2, 0.1, 1).normalized()).norm(), 0, 1e-12);
  EXPECT_NEAR(fp.rms, 0, 1e-9);
  // Two wheels over the hole: too few for a plane, reported.
  const Eigen::Vector3d bad[3] = {{6.5, 6.5, 9}, {6.2, 6.8, 9}, {1, 1, 9}};
  const FootprintPose none = poseFromFootprint(index, std::span(bad), Eigen::Vector3d(1, 0, 0));
  EXPECT_FALSE(none.pose);
  EXPECT_EQ(none.missing.size(), 2u);
  // Least squares over bumpy ground: the fitted normal equals an independent fit of the hits.
  const Mesh bumpy = fractalHeightfield(50, 50, 1.0, 5.0, 9).toMesh();
  const CartesianIndex b(bumpy, CartesianMapping());
  std::vector<Eigen::Vector3d> feet;
  for (int i = 0; i < 8; ++i) feet.emplace_back(20 + 2 * std::cos(i), 20 + 2 * std::sin(i), 100);
  const FootprintPose lsq = poseFromFootprint(b, std::span(feet), Eigen::Vector3d(1, 0, 0));
  ASSERT_TRUE(lsq.pose);
  Eigen::MatrixXd A(8, 3);
  Eigen::VectorXd z(8);
  for (int i = 0; i < 8; ++i) {
    A.row(i) << lsq.hits[i]->world.x(), lsq.hits[i]->world.y(), 1.0;
    z[i] = lsq.hits[i]->world.z();
  }
  // Least squares in z only approximates the orthogonal fit; both agree on gentle slopes.
  const Eigen::Vector3d c = A.colPivHouseholderQr().solve(z);
  EXPECT_NEAR(lsq.up.dot(Eigen::Vector3d(-c[0], -c[1], 1).normalized()), 1, 1e-3);
}

TEST(Pose, OnAPlanetUpIsRadial) {
  const PlanetTerrain planet = loadPlanet(QOTA_DATA_DIR "/etopo20.tif");
  const SphericalIndex index(planet.dem.mesh, planet.mapping);
  // A 4 m car on the flat Pacific floor near 0 N 150 W: up is the radial direction.
  const Eigen::Vector3d centre = planet.mapping.toWorld({-150, 0.001, planet.radius});
  const Eigen::Vector3d east = SphericalMapping::up(-60, 0), north(0, 0, 1);
  const Eigen::Vector3d wheels[4] = {centre + 2 * east + north, centre + 2 * east - north, centre - 2 * east + north,
                                     centre - 2 * east - north};
  const FootprintPose fp = poseFromFootprint(index, std::span(wheels), north);
  ASSERT_TRUE(fp.pose);
  EXPECT_GT(fp.up.dot(SphericalMapping::up(-150, 0)), 0.999);
  EXPECT_LT(planet.mapping.toMapped(fp.pose->position).z(), planet.radius);  // on the sea floor
}

TEST(Move, HolesStepsAndImpassableGround) {
  const Mesh mesh = tiltedPlane(true);
  const CartesianIndex index(mesh, CartesianMapping());
  const Eigen::Vector3d a(2.5, 6.5, 10), b(12.5, 6.5, 10);  // straight through the hole
  EXPECT_TRUE(checkMove(index, a, b).allowed());            // endpoint only: b is on ground
  MoveOptions whole;
  whole.wholePath = true;
  whole.step = 0.1;
  whole.clearance = 20;
  const MoveResult r = checkMove(index, a, b, whole);
  EXPECT_EQ(r.block, MoveBlock::Hole);
  EXPECT_NEAR(r.last.x(), 5.0, 0.11);  // stopped at the hole's rim (x = 5)
  EXPECT_NEAR(r.fraction, 0.25, 0.011);
  const Eigen::Vector3d c(2.5, 2.5, 10), d(12.5, 2.5, 10);  // beside the hole
  EXPECT_TRUE(checkMove(index, c, d, whole).allowed());
  whole.maxStep = 0.01;  // the slope rises 0.02 per 0.1 m step: too steep
  EXPECT_EQ(checkMove(index, c, d, whole).block, MoveBlock::Step);
  whole.maxStep = 1;
  whole.impassable = [](std::uint32_t polygon) { return polygon == 2 * (2 * 20 + 9); };  // a lake
  const MoveResult wet = checkMove(index, c, d, whole);
  EXPECT_EQ(wet.block, MoveBlock::Impassable);
  EXPECT_NEAR(wet.last.x(), 9.0, 0.11);
  EXPECT_EQ(checkMove(index, Eigen::Vector3d(6.5, 6.5, 10), d, whole).block, MoveBlock::Hole);
}

TEST(Move, AroundAStation) {
  const Mesh mesh = stationMesh(fractalHeightfield(360, 50, 1.0, 2.0, 3), {250, 1000});
  const CylindricalIndex index(mesh, CylindricalMapping());
  MoveOptions whole;
  whole.wholePath = true;
  whole.step = 0.5;
  whole.clearance = 5;
  // Ten metres along the floor, crossing the seam at angle 180.
  const Eigen::Vector3d a = index.mapping().toWorld({175, 0, 249}), b = index.mapping().toWorld({-178, 10, 249});
  const MoveResult r = checkMove(index, a, b, whole);
  EXPECT_TRUE(r.allowed());
  EXPECT_NEAR(index.mapping().toMapped(r.last).y(), 10, 1e-9);
}

TEST(Locale, FloorAndCeiling) {
  // A room: floor z = 0 and ceiling z = 3 over [0, 10]^2, a second storey floor at z = 3.5 over
  // half of it, all in one index.
  Mesh m;
  auto quad = [&](double x0, double x1, double z) {
    const auto a = m.addVertex({x0, 0, z}), b = m.addVertex({x1, 0, z}), c = m.addVertex({x1, 10, z}),
               d = m.addVertex({x0, 10, z});
    m.addPolygon({a, b, c, d});
  };
  quad(0, 10, 0);   // polygon 0: floor
  quad(0, 10, 3);   // polygon 1: ceiling
  quad(0, 5, 3.5);  // polygon 2: upper floor
  const CartesianIndex index(m, CartesianMapping());
  const auto isFloor = [](std::uint32_t p) { return p != 1; };
  const auto isCeiling = [](std::uint32_t p) { return p == 1; };
  EXPECT_TRUE(inLocale(index, {5, 5, 1.5}, isFloor, isCeiling));
  EXPECT_FALSE(inLocale(index, {5, 5, 3.2}, isFloor, isCeiling));   // between ceiling and upper floor
  EXPECT_FALSE(inLocale(index, {11, 5, 1.5}, isFloor, isCeiling));  // outside the room
  EXPECT_FALSE(inLocale(index, {2, 5, 4.0}, isFloor, isCeiling));   // upstairs: no ceiling above
  // Two indexes: floor and ceiling apart; the batch equals the single test.
  Mesh floorMesh, ceilMesh;
  std::swap(m, floorMesh);
  quad(0, 10, 0);
  std::swap(m, floorMesh);
  std::swap(m, ceilMesh);
  quad(2, 8, 3);
  std::swap(m, ceilMesh);
  const CartesianIndex floor(floorMesh, CartesianMapping()), ceiling(ceilMesh, CartesianMapping());
  std::mt19937_64 rng(3);
  std::vector<Eigen::Vector3d> points(2000);
  for (auto& p : points) p = {uniform(rng, -1, 11), uniform(rng, -1, 11), uniform(rng, -1, 4)};
  const auto inside = classifyLocale(floor, ceiling, std::span<const Eigen::Vector3d>(points));
  int count = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const auto& p = points[i];
    const bool expect = p.x() >= 2 && p.x() <= 8 && p.y() >= 0 && p.y() <= 10 && p.z() >= 0 && p.z() <= 3;
    ASSERT_EQ(inside[i] != 0, expect) << p.transpose();
    count += expect;
  }
  EXPECT_GT(count, 200);
}

}  // namespace

namespace {

// Scene: parts moving rigidly, checked against one index built from scratch on the moved
// meshes (the same triangles in the world frame).
Mesh transformed(const Mesh& m, const Eigen::Isometry3d& t) {
  Mesh out = m;
  for (auto& v : out.vertices) v = t * v;
  return out;
}

void expectSceneMatchesRebuild(const Scene& scene, const std::vector<const Mesh*>& meshes, std::uint64_t seed) {
  Mesh all;
  std::vector<std::size_t> partOf;
  for (std::size_t k = 0; k < meshes.size(); ++k) {
    const Mesh world = transformed(*meshes[k], scene.transform(k));
    const auto base = static_cast<std::uint32_t>(all.vertices.size());
    all.vertices.insert(all.vertices.end(), world.vertices.begin(), world.vertices.end());
    for (std::size_t p = 0; p < world.polygonCount(); ++p) {
      std::vector<std::uint32_t> idx;
      for (std::uint32_t i : world.polygon(p)) idx.push_back(base + i);
      all.addPolygon(idx);
      partOf.push_back(k);
    }
  }
  const CartesianIndex rebuilt(all, CartesianMapping());
  std::mt19937_64 rng(seed);
  int hits = 0;
  for (int i = 0; i < 3000; ++i) {
    const Eigen::Vector3d p(uniform(rng, 0, 40), uniform(rng, 0, 40), uniform(rng, -5, 25));
    const auto a = scene.below(p);
    const auto b = rebuilt.belowWorld(p);
    ASSERT_EQ(a.has_value(), b.has_value()) << p.transpose();
    if (!a) continue;
    ++hits;
    ASSERT_NEAR(a->hit.height, b->height, 1e-9) << p.transpose();
    ASSERT_EQ(a->part, partOf[b->polygon]) << p.transpose();
    const auto up = scene.above(p);
    const auto upRef = rebuilt.aboveWorld(p);
    ASSERT_EQ(up.has_value(), upRef.has_value());
    if (up) {
      ASSERT_NEAR(up->hit.height, upRef->height, 1e-9);
    }
  }
  EXPECT_GT(hits, 1000);
}

TEST(Scene, MovingAndTiltingPartsMatchARebuild) {
  const Mesh floor = fractalHeightfield(41, 41, 1.0, 3.0, 11).toMesh();  // sea floor, 40 m
  const Mesh deck = fractalHeightfield(11, 21, 1.0, 0.2, 12).toMesh();   // a 10 x 20 m deck
  const CartesianIndex floorIndex(floor, CartesianMapping()), deckIndex(deck, CartesianMapping());
  Scene scene;
  scene.add(floorIndex, Eigen::Isometry3d::Identity(), "floor");
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.translate(Eigen::Vector3d(15, 10, 8)).rotate(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()));
  const std::size_t ship = scene.add(deckIndex, t, "deck");
  EXPECT_EQ(scene.name(ship), "deck");
  const std::vector<const Mesh*> meshes{&floor, &deck};
  expectSceneMatchesRebuild(scene, meshes, 1);  // turned about the vertical: own quadtree

  // The deck rolls and pitches (the world's gravity is oblique in its frame) and moves, frame
  // after frame, without a rebuild.
  for (int frame = 0; frame < 4; ++frame) {
    Eigen::Isometry3d m = Eigen::Isometry3d::Identity();
    m.translate(Eigen::Vector3d(12 + frame, 9, 8 + 0.5 * frame))
        .rotate(Eigen::AngleAxisd(0.2 * frame, Eigen::Vector3d::UnitZ()))
        .rotate(Eigen::AngleAxisd(0.15 - 0.1 * frame, Eigen::Vector3d::UnitX()))
        .rotate(Eigen::AngleAxisd(0.05 * frame, Eigen::Vector3d::UnitY()));
    scene.setTransform(ship, m);
    expectSceneMatchesRebuild(scene, meshes, 2 + frame);
  }
  // Watertight on the tilted deck: straight down through every interior deck vertex (on the
  // rim, rounding may put the line an ulp outside).
  int misses = 0;
  for (std::size_t i = 0; i < deck.vertices.size(); ++i) {
    const int col = static_cast<int>(i % 11), row = static_cast<int>(i / 11);
    if (col == 0 || col == 10 || row == 0 || row == 20) continue;
    const Eigen::Vector3d w = scene.transform(ship) * deck.vertices[i];
    const auto hit = scene.below(w + Eigen::Vector3d(0, 0, 1e-6));
    misses += !hit || hit->part != ship;
  }
  EXPECT_EQ(misses, 0);
  EXPECT_THROW(scene.setTransform(7, Eigen::Isometry3d::Identity()), Error);
}

}  // namespace

namespace {

// The Delft city block: vertical walls are left out of the index (they have no area along
// gravity), so walking into a building finds no ground within a step and stops at its wall;
// water stops a walker by its material.
TEST(Move, CityBlockWallsAndWater) {
  const MeshFile city = loadMeshFile(QOTA_DATA_DIR "/testarea.obj");
  const CartesianIndex index(city.mesh, CartesianMapping({0, 0, -1}, city.origin));
  MoveOptions walk;
  walk.wholePath = true;
  walk.step = 0.25;
  walk.clearance = 0.5;
  walk.maxStep = 0.3;
  walk.impassable = [&](std::uint32_t p) { return city.materialOf(p) == "Water"; };
  // West along y = 447540 from open ground into the building whose wall is near x = 84865.5.
  const MoveResult wall = checkMove(index, {84872, 447540, 0.5}, {84856, 447540, 0.5}, walk);
  EXPECT_EQ(wall.block, MoveBlock::Hole);
  EXPECT_NEAR(wall.last.x(), 84866, 0.6);
  ASSERT_TRUE(wall.ground);
  EXPECT_EQ(city.materialOf(wall.ground->polygon), "Terrain");
  // The roof is found from above, and the ground under the avatar is below it.
  const auto roof = groundUnder(index, Eigen::Vector3d(84860, 447540, 50));
  ASSERT_TRUE(roof);
  EXPECT_EQ(city.materialOf(roof->polygon), "Building");
  EXPECT_GT(roof->height, wall.ground->height + 5);
  // East from the road into the canal.
  const MoveResult wet = checkMove(index, {84903, 447480, 0.5}, {84920, 447480, 0.5}, walk);
  EXPECT_EQ(wet.block, MoveBlock::Impassable);
  EXPECT_NEAR(wet.last.x(), 84910.5, 0.6);
  // Along the road: allowed; the endpoint check alone lets the building walk "teleport" onto
  // nothing, which it refuses too (no ground under the roof within the clearance).
  EXPECT_TRUE(checkMove(index, {84937, 447480, 0.5}, {84952, 447480, 0.5}, walk).allowed());
  MoveOptions endpoint = walk;
  endpoint.wholePath = false;
  EXPECT_EQ(checkMove(index, {84872, 447540, 0.5}, {84856, 447540, 0.5}, endpoint).block, MoveBlock::Hole);
}

}  // namespace

namespace {

// Containment on a planet: the locale between the ground (floor) and a shell 10 km above the
// reference sphere (ceiling), two spherical indexes.
TEST(Locale, BetweenAPlanetAndAShell) {
  const PlanetTerrain planet = loadPlanet(QOTA_DATA_DIR "/etopo20.tif");
  const SphericalIndex ground(planet.dem.mesh, planet.mapping);
  Mesh shell = planet.dem.mesh;
  for (auto& v : shell.vertices) v = v.normalized() * (planet.radius + 10000);
  const SphericalIndex sky(shell, planet.mapping);
  std::mt19937_64 rng(8);
  for (int i = 0; i < 2000; ++i) {
    const double lon = uniform(rng, -180, 180), lat = uniform(rng, -89, 89);
    const double r = planet.radius + uniform(rng, -12000, 12000);
    const Eigen::Vector3d p = planet.mapping.toWorld({lon, lat, r});
    const double groundR = *ground.height(lon, lat), skyR = *sky.height(lon, lat);
    const bool expect = r >= groundR && r <= skyR;
    ASSERT_EQ(inLocale(ground, sky, p), expect) << lon << " " << lat << " " << r;
  }
}

}  // namespace

namespace {

// A scene in a curved world: a planet that spins, and a raft (a Cartesian part) riding on it,
// checked against one spherical index built from scratch on the moved meshes.
TEST(Scene, CurvedWorldMatchesARebuild) {
  std::mt19937_64 rng(31);
  Mesh planetMesh;
  {
    // A bumpy sphere of radius 1000 from a lon/lat grid with closed caps.
    const int nlon = 72, nlat = 35;
    for (int j = 0; j < nlat; ++j) {
      for (int i = 0; i < nlon; ++i) {
        const double lon = -180 + 5.0 * i + 2.5, lat = -85 + 5.0 * j;
        planetMesh.addVertex((1000 + uniform(rng, -5, 5)) * SphericalMapping::up(lon, lat));
      }
    }
    const auto north = planetMesh.addVertex({0, 0, 1000}), south = planetMesh.addVertex({0, 0, -1000});
    for (int j = 0; j + 1 < nlat; ++j) {
      for (int i = 0; i < nlon; ++i) {
        const auto a = static_cast<std::uint32_t>(j * nlon + i),
                   b = static_cast<std::uint32_t>(j * nlon + (i + 1) % nlon);
        planetMesh.addTriangle(a, b, b + nlon);
        planetMesh.addTriangle(a, b + nlon, a + nlon);
      }
    }
    for (int i = 0; i < nlon; ++i) {
      planetMesh.addTriangle(static_cast<std::uint32_t>((nlat - 1) * nlon + i),
                             static_cast<std::uint32_t>((nlat - 1) * nlon + (i + 1) % nlon), north);
      planetMesh.addTriangle(static_cast<std::uint32_t>(i), static_cast<std::uint32_t>((i + 1) % nlon), south);
    }
  }
  const Mesh raftMesh = fractalHeightfield(11, 11, 2.0, 0.3, 4).toMesh();  // 20 x 20 m deck
  const SphericalMapping world;
  const SphericalIndex planet(planetMesh, world);
  const CartesianIndex raft(raftMesh, CartesianMapping());
  Scene scene{AnyMapping(world)};
  const std::size_t spinning = scene.add(planet, Eigen::Isometry3d::Identity(), "planet");
  const std::size_t boat = scene.add(raft, Eigen::Isometry3d::Identity(), "raft");
  for (int frame = 0; frame < 3; ++frame) {
    Eigen::Isometry3d spin = Eigen::Isometry3d::Identity();
    spin.rotate(Eigen::AngleAxisd(0.1 * frame, Eigen::Vector3d::UnitZ()));
    scene.setTransform(spinning, spin);
    // The raft 30 m above the ground at 20 N 40 E, its z along the radial, turned and tilted.
    const Eigen::Vector3d upDir = SphericalMapping::up(40, 20);
    Eigen::Isometry3d place = Eigen::Isometry3d::Identity();
    place.translate(1030 * upDir);
    place.rotate(Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), upDir));
    place.rotate(Eigen::AngleAxisd(0.3 * frame, Eigen::Vector3d::UnitZ()));
    place.rotate(Eigen::AngleAxisd(0.05 * frame, Eigen::Vector3d::UnitX()));
    place.translate(Eigen::Vector3d(-10, -10, 0));
    scene.setTransform(boat, place);
    // The oracle: both meshes moved into the world, one spherical index.
    Mesh all = transformed(planetMesh, spin);
    const std::size_t raftFirst = all.polygonCount();
    const Mesh moved = transformed(raftMesh, place);
    const auto base = static_cast<std::uint32_t>(all.vertices.size());
    all.vertices.insert(all.vertices.end(), moved.vertices.begin(), moved.vertices.end());
    for (std::size_t p = 0; p < moved.polygonCount(); ++p) {
      const auto t = moved.polygon(p);
      all.addTriangle(base + t[0], base + t[1], base + t[2]);
    }
    const SphericalIndex oracle(all, world);
    int onRaft = 0;
    for (int i = 0; i < 4000; ++i) {
      // Around the raft, and anywhere.
      const double lon = i % 2 ? uniform(rng, 39.95, 40.05) : uniform(rng, -180, 180);
      const double lat = i % 2 ? uniform(rng, 19.95, 20.05) : uniform(rng, -80, 80);
      const Eigen::Vector3d p = world.toWorld({lon, lat, uniform(rng, 990, 1040)});
      const auto a = scene.below(p);
      const Eigen::Vector3d m = world.toMapped(p);
      const auto b = oracle.below(m.x(), m.y(), m.z());
      ASSERT_EQ(a.has_value(), b.has_value()) << lon << " " << lat;
      if (!a) continue;
      ASSERT_NEAR(a->hit.height, b->height, 1e-9 * b->height);
      ASSERT_EQ(a->part, b->polygon >= raftFirst ? boat : spinning);
      onRaft += a->part == boat;
    }
    EXPECT_GT(onRaft, 100);
  }
  // A curved part moved off its centre: the world's lines are no longer its own, and it answers
  // along them exactly (alongLine), as the moved mesh in one spherical index does.
  Eigen::Isometry3d shift = Eigen::Isometry3d::Identity();
  shift.translate(Eigen::Vector3d(5, 0, 0));
  scene.setTransform(spinning, shift);
  scene.setTransform(boat, Eigen::Isometry3d(Eigen::Translation3d(0, 0, 1e7)));  // out of the way
  const SphericalIndex shifted(transformed(planetMesh, shift), world);
  for (int i = 0; i < 50; ++i) {
    const Eigen::Vector3d p = world.toWorld({uniform(rng, -180, 180), uniform(rng, -80, 80), uniform(rng, 990, 1040)});
    const auto a = scene.below(p);
    const Eigen::Vector3d m = world.toMapped(p);
    const auto b = shifted.below(m.x(), m.y(), m.z());
    ASSERT_EQ(a.has_value(), b.has_value());
    if (a) {
      EXPECT_NEAR(a->hit.height, b->height, 1e-9 * b->height);
    }
  }
}

}  // namespace
