// Drive a rover across the whole Earth under radial gravity: the bundled 20-arc-minute global
// DEM is closed into a planet (spherical mapping, centre at the origin), and the rover follows
// the great circle from Lisbon over Scandinavia and Siberia to Tokyo, then on across the Pacific
// and New Zealand's South Island, over the antimeridian into the Southern Ocean. At every step
// it asks the QOTA index for the ground under it and prints the height above the reference
// sphere, the local up (the unit radial direction) and the surface normal. The planet
// is a closed surface, so every step must find ground; a last query stands exactly on the north
// pole.
//
//   rover_planet [DEM]      (default: the bundled data/etopo20.tif, a 1080 x 540 lon/lat grid)
#include <GeographicLib/Geodesic.hpp>
#include <GeographicLib/GeodesicLine.hpp>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>
#include <numbers>
#include <string>

#include "qota/curved.hpp"
#include "qota/error.hpp"
#include "qota/globe.hpp"

int main(int argc, char** argv) {
  const std::string path = argc > 1 ? argv[1] : QOTA_DATA_DIR "/etopo20.tif";
  try {
    const qota::PlanetTerrain planet = qota::loadPlanet(path);  // radius: from the raster's CRS
    const qota::SphericalIndex index(planet.dem.mesh, planet.mapping);
    std::printf("%s: planet of radius %.1f m, %llu triangles, quadtree of %llu nodes\n", path.c_str(), planet.radius,
                static_cast<unsigned long long>(index.stats().triangles),
                static_cast<unsigned long long>(index.stats().tree.nodes));

    // The route: a great circle on a sphere of the planet's radius (flattening 0), from Lisbon
    // towards Tokyo, driven 12,000 km past Tokyo so that it crosses the antimeridian (lon +180
    // -> -180), where the last and first columns of the raster are joined.
    const double latLisbon = 38.7, lonLisbon = -9.1, latTokyo = 35.7, lonTokyo = 139.7;
    const GeographicLib::Geodesic sphere(planet.radius, 0);
    const GeographicLib::GeodesicLine route = sphere.InverseLine(latLisbon, lonLisbon, latTokyo, lonTokyo);
    const double length = route.Distance() + 1.2e7;  // metres along the route
    const int steps = 60;

    std::printf("%4s %9s %8s %8s %22s %22s %6s\n", "step", "lon", "lat", "height", "up (x y z)", "normal (x y z)",
                "slope");
    int misses = 0;
    double lastLon = lonLisbon;
    for (int i = 0; i <= steps; ++i) {
      double lat, lon;
      route.Position(length * i / steps, lat, lon);  // lon comes back in [-180, 180]
      if (lastLon > 90 && lon < -90) std::printf("---- crossed the antimeridian ----\n");
      lastLon = lon;
      const auto hit = index.top(lon, lat);
      if (!hit) {
        ++misses;
        std::printf("%4d %9.3f %8.3f %8s\n", i, lon, lat, "none");
        continue;
      }
      const Eigen::Vector3d up = qota::SphericalMapping::up(lon, lat);
      // The angle between the ground and the local horizontal, from the normal and the up.
      const double slope = std::acos(std::clamp(up.dot(hit->normal), -1.0, 1.0)) * 180.0 / std::numbers::pi;
      std::printf("%4d %9.3f %8.3f %8.1f %7.4f %7.4f %7.4f %7.4f %7.4f %7.4f %6.2f\n", i, lon, lat,
                  hit->height - planet.radius, up.x(), up.y(), up.z(), hit->normal.x(), hit->normal.y(),
                  hit->normal.z(), slope);
    }

    // The seam: lon +180 and -180 are the same meridian, so both must give the same ground.
    const auto east = index.top(180.0, -52.0), west = index.top(-180.0, -52.0);
    if (east && west) {
      std::printf("seam at lat -52: lon +180 -> %.1f m, lon -180 -> %.1f m\n", east->height - planet.radius,
                  west->height - planet.radius);
    } else {
      ++misses;
      std::printf("seam at lat -52: none\n");
    }

    // Bonus: stand exactly on the north pole, where every longitude names the same line.
    const auto pole = index.top(0.0, 90.0);
    if (pole) {
      std::printf("north pole: height %.1f m, world z %.1f m, normal %.4f %.4f %.4f\n", pole->height - planet.radius,
                  pole->world.z(), pole->normal.x(), pole->normal.y(), pole->normal.z());
    } else {
      ++misses;
      std::printf("north pole: none\n");
    }

    std::printf("route done: %d steps, %d misses\n", steps + 1, misses);
    return misses == 0 ? 0 : 1;
  } catch (const qota::Error& e) {
    std::fprintf(stderr, "rover_planet: %s\n", e.what());
    return 1;
  }
}
