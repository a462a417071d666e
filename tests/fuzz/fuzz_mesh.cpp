// Mesh files: the first byte picks the reader (qota's OBJ, Assimp's PLY, OFF, STL, OGR's GeoJSON
// and DXF), the rest is the file; a mesh that loads is indexed and queried.
#include <array>

#include "fuzz_common.hpp"
#include "qota/error.hpp"
#include "qota/mesh_io.hpp"
#include "qota/terrain.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static constexpr std::array<const char*, 6> kNames = {"input.obj", "input.ply",     "input.off",
                                                        "input.stl", "input.geojson", "input.dxf"};
  if (size == 0) return 0;
  const std::string path = qota::fuzz::writeFile(kNames[data[0] % kNames.size()], data + 1, size - 1);
  try {
    qota::MeshFileOptions options;
    options.triangulate = (data[0] / kNames.size()) % 2 == 1;
    options.readerSeconds = 2;  // a hang in Assimp's parsers is an error after this
    const qota::MeshFile file = qota::loadMeshFile(path, options);
    const qota::CartesianIndex index(file.mesh, qota::CartesianMapping(Eigen::Vector3d(0, 0, -1), file.origin));
    const qota::Box2 box = index.tree().box();
    for (int i = 0; i <= 4; ++i) {
      const double u = box.ulo + (box.uhi - box.ulo) * i / 4, v = box.vlo + (box.vhi - box.vlo) * i / 4;
      (void)index.top(u, v);
      (void)index.below(u, v, 0.0);
    }
  } catch (const qota::Error&) {
  }
  return 0;
}
