// A terrain as a polygon soup: world-frame vertices and convex polygons given by vertex indices.
// Polygons may overlap and need not be connected; gaps between them are holes. Winding does not
// matter. This is what every terrain source (rasters, mesh files) produces and what every index
// (index.hpp) builds from.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <initializer_list>
#include <span>
#include <vector>

namespace qota {

struct Mesh {
  std::vector<Eigen::Vector3d> vertices;  // world frame, double precision
  std::vector<std::uint32_t> indices;     // polygon vertex indices, polygons one after another
  // Polygon p uses indices[offsets[p] .. offsets[p + 1]). Empty while every polygon is a
  // triangle (the common case, which then costs no offset array): polygon p is indices[3p .. 3p+3).
  std::vector<std::uint32_t> offsets;

  std::size_t polygonCount() const { return offsets.empty() ? indices.size() / 3 : offsets.size() - 1; }
  std::span<const std::uint32_t> polygon(std::size_t p) const {
    if (offsets.empty()) return {indices.data() + 3 * p, 3};
    return {indices.data() + offsets[p], offsets[p + 1] - offsets[p]};
  }

  std::uint32_t addVertex(const Eigen::Vector3d& p) {
    vertices.push_back(p);
    return static_cast<std::uint32_t>(vertices.size() - 1);
  }
  void addTriangle(std::uint32_t a, std::uint32_t b, std::uint32_t c) {
    indices.insert(indices.end(), {a, b, c});
    if (!offsets.empty()) offsets.push_back(static_cast<std::uint32_t>(indices.size()));
  }
  void addPolygon(std::span<const std::uint32_t> corners) {
    if (offsets.empty() && corners.size() != 3) {
      // First non-triangle: switch to explicit offsets for everything so far.
      offsets.reserve(polygonCount() + 2);
      for (std::size_t p = 0; p <= indices.size() / 3; ++p) {
        offsets.push_back(static_cast<std::uint32_t>(3 * p));
      }
    }
    indices.insert(indices.end(), corners.begin(), corners.end());
    if (!offsets.empty()) offsets.push_back(static_cast<std::uint32_t>(indices.size()));
  }
  void addPolygon(std::initializer_list<std::uint32_t> corners) {
    addPolygon(std::span<const std::uint32_t>(corners.begin(), corners.size()));
  }
};

// A raster's mesh without its index list: width x height vertices in row order (world x, y and
// the height, NaN where the raster has no data) and the raster rule's inner triangles over them
// (raster_grid.hpp), the ones whose three corners have data, each in the opposite turn when
// `reverse`. An index built from it is the index of the Mesh that RasterGrid's appendTriangles
// would make (toMesh), bit for bit, built without making that mesh (a sampler's tiles).
struct GridMesh {
  int width = 0, height = 0;
  std::span<const Eigen::Vector3d> vertices;  // width * height
  bool reverse = false;

  static bool hasData(const Eigen::Vector3d& p) { return !std::isnan(p.z()); }
  std::uint64_t polygonCount() const;  // the triangles with data (raster_grid.cpp)
  Mesh toMesh() const;
};

}  // namespace qota
