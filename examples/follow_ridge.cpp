// Follow the terrain from Paradise up to the summit of Mount Rainier on the bundled SRTM tile:
// build the QOTA index once, then place an object on the ground every few hundred metres and
// print its height, surface normal and the model matrix a renderer (glm) would use.
//
//   follow_ridge [DEM]      (default: the bundled data/mt_rainier_90m.tif)
#include <cstdio>
#include <exception>
#include <string>

#include "qota/dem.hpp"
#include "qota/error.hpp"
#include "qota/glm_interop.hpp"
#include "qota/terrain.hpp"

int main(int argc, char** argv) {
  const std::string path = argc > 1 ? argv[1] : QOTA_DATA_DIR "/mt_rainier_90m.tif";
  try {
    const qota::DemTerrain dem = qota::loadDem(path);
    const qota::TerrainIndex index(dem.mesh, dem.mapping);
    std::printf("%s: %llu triangles, quadtree of %llu nodes\n", path.c_str(),
                static_cast<unsigned long long>(index.stats().triangles),
                static_cast<unsigned long long>(index.stats().tree.nodes));

    // Paradise visitor centre to the summit, in the raster's CRS (degrees).
    const double lon0 = -121.7353, lat0 = 46.7865, lon1 = -121.7603, lat1 = 46.8529;
    const int steps = 12;
    std::printf("%10s %10s %9s %22s\n", "lon", "lat", "height", "normal (x y z)");
    for (int i = 0; i <= steps; ++i) {
      const double t = static_cast<double>(i) / steps;
      const Eigen::Vector3d p(lon0 + t * (lon1 - lon0), lat0 + t * (lat1 - lat0), 0.0);
      const auto hit = index.topWorld(p);
      if (!hit) {
        std::printf("%10.5f %10.5f %9s\n", p.x(), p.y(), "none");
        continue;
      }
      std::printf("%10.5f %10.5f %9.1f %7.3f %7.3f %7.3f\n", p.x(), p.y(), hit->height,
                  hit->normal.x(), hit->normal.y(), hit->normal.z());
      if (i == steps) {
        // The pose of a marker standing on the summit, heading north, as a glm matrix.
        const glm::dmat4 m = qota::toGlm(qota::poseOnHit(*hit, Eigen::Vector3d(0, 1, 0)));
        std::printf("summit marker model matrix (column-major): translation %.5f %.5f %.1f\n",
                    m[3][0], m[3][1], m[3][2]);
      }
    }
    return 0;
  } catch (const qota::Error& e) {
    std::fprintf(stderr, "follow_ridge: %s\n", e.what());
    return 1;
  }
}
