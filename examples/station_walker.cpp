// Walk once around the inside of a rotating space station. The station is a cylinder of radius
// 250 m and length 1000 m spinning about the world z axis; its floor carries a fractal relief
// whose hills rise toward the axis. Spin gravity pulls away from the axis, so the cylindrical
// mapping's "down" points outward: u is the angle around the axis (degrees), v the position along
// it, h the distance from it, and the floor is at large h. The walker goes one full turn and a
// bit more (0 to 400 degrees, across the seam at +-180 and past its start), asking the QOTA
// index for the floor under its feet at every step, and prints the floor's distance from the
// axis, the relief height, the local up (toward the axis) and the surface normal.
//
//   station_walker
#include <cmath>
#include <cstdio>
#include <exception>
#include <numbers>

#include "qota/curved.hpp"
#include "qota/cylindrical.hpp"
#include "qota/error.hpp"
#include "qota/globe.hpp"
#include "qota/synthetic.hpp"

int main() {
  try {
    // 360 columns around the axis (one a degree) by 100 rings along it, relief about +-8 m.
    const qota::Heightfield relief = qota::fractalHeightfield(360, 100, 1.0, 8.0, 7);
    qota::StationOptions station;
    station.radius = 250;
    station.length = 1000;
    const qota::Mesh mesh = qota::stationMesh(relief, station);
    const qota::CylindricalMapping mapping;  // axis: world z through the origin
    const qota::CylindricalIndex index(mesh, mapping);
    std::printf("station r=%.0f m, length %.0f m: %llu triangles, quadtree of %llu nodes\n", station.radius,
                station.length, static_cast<unsigned long long>(index.stats().triangles),
                static_cast<unsigned long long>(index.stats().tree.nodes));

    // Spin for 1 g at the zero level of the relief: omega^2 r = g.
    const double g0 = 9.81, omega = std::sqrt(g0 / station.radius);
    std::printf("spin %.4f rad/s (one turn in %.1f s) for 1 g at r = %.0f m\n", omega, 2.0 * std::numbers::pi / omega,
                station.radius);

    const double v = 100.0;  // metres along the axis
    const int steps = 40;    // 10 degrees a step, 0 to 400 degrees
    std::printf("%6s %9s %8s %22s %22s %8s\n", "angle", "r_floor", "relief", "up (x y z)", "normal (x y z)", "g");
    int misses = 0;
    for (int i = 0; i <= steps; ++i) {
      const double angle = 10.0 * i;         // any angle: the index wraps it to [-180, 180)
      const auto hit = index.top(angle, v);  // the floor surface nearest the axis
      if (!hit) {
        ++misses;
        std::printf("%6.1f %9s\n", angle, "none");
        continue;
      }
      // Up points from the floor toward the axis: against the outward "down" of the mapping.
      const Eigen::Vector3d up = -mapping.out(angle);
      // Spin gravity felt at this floor point: omega^2 times the distance from the axis.
      const double g = omega * omega * hit->height;
      std::printf("%6.1f %9.3f %8.3f %7.4f %7.4f %7.4f %7.4f %7.4f %7.4f %8.4f\n", angle, hit->height,
                  station.radius - hit->height, up.x(), up.y(), up.z(), hit->normal.x(), hit->normal.y(),
                  hit->normal.z(), g);
    }
    std::printf("walk done: %d steps, %d misses\n", steps + 1, misses);
    return misses == 0 ? 0 : 1;
  } catch (const qota::Error& e) {
    std::fprintf(stderr, "station_walker: %s\n", e.what());
    return 1;
  }
}
