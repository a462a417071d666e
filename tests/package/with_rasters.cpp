// A DEM through GDAL: the height at Mount Rainier's summit from the bundled SRTM tile, in metres.
#include <cstdio>
#include <qota/globe.hpp>
#include <qota/curved.hpp>

int main(int argc, char** argv) {
  if (argc != 2) return 2;
  const qota::EllipsoidTerrain rainier = qota::loadOnEllipsoid(argv[1]);
  const qota::GeodeticIndex index(rainier.dem.mesh, rainier.mapping);
  const auto summit = index.top(-121.7603, 46.8529);
  std::printf("%.0f\n", summit ? summit->height : -1.0);
  return summit && summit->height > 4300 && summit->height < 4400 ? 0 : 1;
}
