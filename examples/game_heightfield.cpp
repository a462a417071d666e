// Terrain following with the core alone (qota::core: no GDAL, no Assimp, no libnova), as a game
// or a robot would embed it: a procedural heightfield, indexed once; a vehicle placed on its four
// wheels every step of a drive, stopped by a cliff (its top is no ground within the vehicle's
// reach: walls are not terrain).
#include <cmath>
#include <cstdio>
#include <span>

#include "qota/follow.hpp"
#include "qota/synthetic.hpp"
#include "qota/terrain.hpp"

int main() {
  // 256 x 256 vertices, 2 m apart, up to 12 m of relief, and a 30 m cliff across x = 400.
  qota::Heightfield field = qota::fractalHeightfield(256, 256, 2.0, 12.0, 7);
  for (int j = 0; j < field.ny; ++j) {
    for (int i = 200; i < field.nx; ++i) field.z[static_cast<std::size_t>(j) * field.nx + i] += 30.0;
  }
  const qota::CartesianIndex index(field.toMesh(), qota::CartesianMapping());

  const Eigen::Vector3d heading(1, 0, 0), right(0, -1, 0);
  int placed = 0;
  Eigen::Vector3d at = index.topWorld({20, 250, 0})->world;  // standing on the ground
  for (int step = 0; step < 200; ++step) {
    const Eigen::Vector3d next = at + 2.0 * heading;  // checkMove drops it onto the ground
    qota::MoveOptions move;
    move.maxStep = 1.0;  // the vehicle climbs at most 1 m per 2 m step
    move.wholePath = true;
    move.step = 0.5;
    move.clearance = 2.0;
    const qota::MoveResult check = qota::checkMove(index, at, next, move);
    if (!check.allowed()) {
      std::printf("stopped at x = %.1f: %s\n", at.x(),
                  check.block == qota::MoveBlock::Hole ? "no ground ahead" : "a step higher than it can climb");
      break;
    }
    at = check.ground->world;
    const Eigen::Vector3d wheels[4] = {at + 1.5 * heading + right, at + 1.5 * heading - right,
                                       at - 1.5 * heading + right, at - 1.5 * heading - right};
    const qota::FootprintPose fp = qota::poseFromFootprint(index, std::span(wheels), heading);
    if (fp.pose) ++placed;
  }
  std::printf("drive done: %d poses\n", placed);
  return 0;
}
