// Drive a car over Mount St. Helens (the bundled 1980 USGS DEM, UTM metres): every metre or so,
// the car's four wheels are dropped onto the terrain and the car is placed on the plane through
// them (the paper's footprint method, least squares over four wheels), keeping its heading as
// seen from above. Prints the pose every 200 m: position, pitch and roll, and at the end the
// model matrix a renderer would use (glm).
//
//   drive_car [DEM]      (default: the bundled data/SainteHelens.dem)
#include <cmath>
#include <cstdio>
#include <exception>
#include <numbers>
#include <string>

#include "qota/dem.hpp"
#include "qota/error.hpp"
#include "qota/follow.hpp"
#include "qota/glm_interop.hpp"
#include "qota/terrain.hpp"

int main(int argc, char** argv) {
  const std::string path = argc > 1 ? argv[1] : QOTA_DATA_DIR "/SainteHelens.dem";
  try {
    const qota::DemTerrain dem = qota::loadDem(path);
    const qota::CartesianIndex index(dem.mesh, dem.mapping);
    // A drive of about 2.4 km north-east, up the volcano's flank, heading along the route.
    const auto a = dem.pixelCentre(dem.width * 0.3, dem.height * 0.6);
    const auto b = dem.pixelCentre(dem.width * 0.5, dem.height * 0.5);
    const Eigen::Vector3d start(a[0], a[1], 0), end(b[0], b[1], 0);
    const Eigen::Vector3d heading = (end - start).normalized();
    const Eigen::Vector3d right = heading.cross(Eigen::Vector3d::UnitZ()).normalized();
    const double length = (end - start).norm(), halfLength = 2.0, halfWidth = 0.9;
    std::printf("%s: driving %.0f m, a car of %.1f x %.1f m\n", path.c_str(), length, 2 * halfLength, 2 * halfWidth);
    std::printf("%8s %12s %12s %9s %7s %7s %s\n", "metres", "x", "y", "z", "pitch", "roll", "wheels off");
    qota::Pose pose;
    int placed = 0, wheelsOff = 0;
    for (double s = 0; s <= length; s += 1.0) {
      const Eigen::Vector3d c = start + s * heading;
      const Eigen::Vector3d wheels[4] = {
          c + halfLength * heading + halfWidth * right, c + halfLength * heading - halfWidth * right,
          c - halfLength * heading + halfWidth * right, c - halfLength * heading - halfWidth * right};
      const qota::FootprintPose fp = qota::poseFromFootprint(index, std::span(wheels), heading);
      wheelsOff += static_cast<int>(fp.missing.size());
      if (!fp.pose) continue;  // over a hole: keep the last pose
      pose = *fp.pose;
      ++placed;
      if (std::fmod(s, 200.0) == 0) {
        const Eigen::Vector3d x = pose.orientation.col(0), y = pose.orientation.col(1);
        const double pitch = std::asin(x.z()) * 180 / std::numbers::pi;
        const double roll = std::asin(y.z()) * 180 / std::numbers::pi;
        std::printf("%8.0f %12.2f %12.2f %9.2f %7.2f %7.2f %zu\n", s, pose.position.x(), pose.position.y(),
                    pose.position.z(), pitch, roll, fp.missing.size());
      }
    }
    const glm::dmat4 m = qota::toGlm(pose);
    std::printf("model matrix at the end (glm, column-major):\n");
    for (int r = 0; r < 4; ++r) {
      std::printf("  %9.4f %9.4f %9.4f %12.2f\n", m[0][r], m[1][r], m[2][r], m[3][r]);
    }
    std::printf("drive done: %d poses, %d wheel samples over holes\n", placed, wheelsOff);
    return 0;
  } catch (const qota::Error& e) {
    std::fprintf(stderr, "drive_car: %s\n", e.what());
    return 1;
  }
}
