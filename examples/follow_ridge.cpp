// Follow the terrain from Paradise up to the summit of Mount Rainier on the bundled SRTM tile:
// the tile is in longitude/latitude, so it is put on its WGS84 ellipsoid (the geodetic mapping:
// metres everywhere, "down" along the ellipsoid normal), indexed once, and an object is placed on
// the ground every few hundred metres. Prints its height, the slope and aspect of the ground
// under it (from the surface normal, in the local east-north-up frame) and, at the summit, the
// model matrix a renderer (glm) would use, in geocentric metres.
//
//   follow_ridge [DEM]      (default: the bundled data/mt_rainier_90m.tif; any lon/lat raster)
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>
#include <numbers>
#include <string>

#include "qota/curved.hpp"
#include "qota/error.hpp"
#include "qota/glm_interop.hpp"
#include "qota/globe.hpp"

int main(int argc, char** argv) {
  const std::string path = argc > 1 ? argv[1] : QOTA_DATA_DIR "/mt_rainier_90m.tif";
  try {
    // SRTM leaves voids on the steepest slopes near the summit; filled first, as gdal_fillnodata
    // would, the walk never falls through one.
    const qota::EllipsoidTerrain terrain = qota::loadOnEllipsoid(path, {.fillVoids = qota::kFillVoidsPixels});
    const qota::GeodeticIndex index(terrain.dem.mesh, terrain.mapping);
    std::printf("%s on its ellipsoid: %llu triangles\n", path.c_str(),
                static_cast<unsigned long long>(terrain.dem.mesh.polygonCount()));

    // Paradise visitor centre to the summit (longitude, latitude in degrees).
    const double lon0 = -121.7353, lat0 = 46.7865, lon1 = -121.7603, lat1 = 46.8529;
    const int steps = 12;
    const double deg = std::numbers::pi / 180;
    std::printf("%10s %10s %9s %7s %7s\n", "lon", "lat", "height", "slope", "aspect");
    double steepest = 0;
    for (int i = 0; i <= steps; ++i) {
      const double t = static_cast<double>(i) / steps;
      const double lon = lon0 + t * (lon1 - lon0), lat = lat0 + t * (lat1 - lat0);
      const auto hit = index.top(lon, lat);  // height along the ellipsoid normal, metres
      if (!hit) {
        std::printf("%10.5f %10.5f %9s\n", lon, lat, "none");
        continue;
      }
      // East, north and up of the ellipsoid at this point (geocentric unit vectors).
      const Eigen::Vector3d east(-std::sin(lon * deg), std::cos(lon * deg), 0);
      const Eigen::Vector3d up(std::cos(lat * deg) * std::cos(lon * deg), std::cos(lat * deg) * std::sin(lon * deg),
                               std::sin(lat * deg));
      const Eigen::Vector3d north = up.cross(east);
      const Eigen::Vector3d n = hit->normal;
      const double slope = std::acos(std::min(1.0, n.dot(up))) / deg;
      const double aspect = std::fmod(std::atan2(n.dot(east), n.dot(north)) / deg + 360, 360);  // downhill
      std::printf("%10.5f %10.5f %9.1f %7.1f %7.0f\n", lon, lat, hit->height, slope, aspect);
      steepest = std::max(steepest, slope);
      if (i == steps) {
        // The pose of a marker standing on the summit, heading north, as a glm matrix.
        const glm::dmat4 m = qota::toGlm(qota::poseOnHit(*hit, north));
        std::printf("summit marker model matrix (column-major, geocentric metres): translation %.1f %.1f %.1f\n",
                    m[3][0], m[3][1], m[3][2]);
      }
    }
    std::printf("steepest ground: %.1f degrees\n", steepest);
    return 0;
  } catch (const qota::Error& e) {
    std::fprintf(stderr, "follow_ridge: %s\n", e.what());
    return 1;
  }
}
