// A flat square at z = 100 seen from above: the height under its middle is 100.
#include <cstdio>
#include <qota/terrain.hpp>
#include <qota/version.hpp>

int main() {
  qota::Mesh mesh;
  const auto a = mesh.addVertex({0, 0, 100}), b = mesh.addVertex({10, 0, 100});
  const auto c = mesh.addVertex({10, 10, 100}), d = mesh.addVertex({0, 10, 100});
  mesh.addPolygon({a, b, c, d});
  const qota::CartesianIndex index(mesh, qota::CartesianMapping());
  const auto h = index.height(5, 5);
  std::printf("qota %s: %g\n", QOTA_VERSION_STRING, h ? *h : -1.0);
  return h && *h == 100 ? 0 : 1;
}
