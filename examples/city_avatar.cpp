// An avatar walking in a real city block (Delft, the bundled 3dfier model: terrain, roads,
// water and 160 buildings). The index follows gravity, so the vertical walls of buildings are
// not terrain: walking into a building finds no ground within a step's height (the roofs are
// far above), and the move stops at the wall, as the paper's collision with holes does. Water is
// marked impassable by its material. Each walk prints where it stopped and why.
//
//   city_avatar [OBJ]      (default: the bundled data/testarea.obj)
#include <cstdio>
#include <exception>
#include <string>

#include "qota/error.hpp"
#include "qota/follow.hpp"
#include "qota/mesh_io.hpp"
#include "qota/terrain.hpp"

namespace {

const char* why(qota::MoveBlock b) {
  switch (b) {
    case qota::MoveBlock::None:
      return "arrived";
    case qota::MoveBlock::Hole:
      return "stopped: no ground ahead (a wall, a hole)";
    case qota::MoveBlock::Step:
      return "stopped: a step higher than the avatar can climb";
    case qota::MoveBlock::Impassable:
      return "stopped: impassable ground";
  }
  return "?";
}

}  // namespace

int main(int argc, char** argv) {
  const std::string path = argc > 1 ? argv[1] : QOTA_DATA_DIR "/testarea.obj";
  try {
    const qota::MeshFile city = qota::loadMeshFile(path);
    // Map coordinates in the hundreds of thousands: an origin at the model's centre keeps them
    // precise in the index.
    const qota::CartesianIndex index(city.mesh, qota::CartesianMapping({0, 0, -1}, city.origin));
    std::printf("%s: %zu polygons, %llu walls left out of the index\n", path.c_str(), city.mesh.polygonCount(),
                static_cast<unsigned long long>(index.stats().leftOut));
    qota::MoveOptions walk;
    walk.wholePath = true;
    walk.step = 0.25;      // metres between samples
    walk.clearance = 0.5;  // how far above its feet the avatar looks for ground
    walk.maxStep = 0.3;    // the highest step it climbs
    walk.impassable = [&](std::uint32_t polygon) { return city.materialOf(polygon) == "Water"; };

    struct Walk {
      const char* name;
      Eigen::Vector3d from, to;
    };
    const Walk walks[] = {
        // Feet at street level (about 0 m NAP); roofs are some 8 m up.
        {"west into a building", {84872.0, 447540.0, 0.5}, {84856.0, 447540.0, 0.5}},
        {"east into the canal", {84903.0, 447480.0, 0.5}, {84920.0, 447480.0, 0.5}},
        {"along the street", {84937.0, 447480.0, 0.5}, {84952.0, 447480.0, 0.5}},
    };
    for (const Walk& w : walks) {
      const qota::MoveResult r = qota::checkMove(index, w.from, w.to, walk);
      const double walked = r.fraction * (w.to - w.from).norm();
      std::printf("%-24s %-44s after %5.2f m at (%.2f, %.2f, %.2f) on %s\n", w.name, why(r.block), walked, r.last.x(),
                  r.last.y(), r.last.z(), r.ground ? city.materialOf(r.ground->polygon).c_str() : "nothing");
    }
    std::printf("walks done\n");
    return 0;
  } catch (const qota::Error& e) {
    std::fprintf(stderr, "city_avatar: %s\n", e.what());
    return 1;
  }
}
