// How the triangles of a shadow frame face a light, and which pixels the light reaches from below
// their own surface (attached shadow). Internal to the shadow code (shadow.cpp, shadow_strips.cpp).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <span>
#include <thread>
#include <vector>

#include "qota/shadow_frame.hpp"

namespace qota::shadow {

// Triangles around each vertex, as offsets into one list, for a frame whose mesh is not
// localFrame's grid.
struct VertexStar {
  std::vector<std::uint32_t> start, tris;
  explicit VertexStar(const Mesh& mesh) : start(mesh.vertices.size() + 1, 0) {
    for (std::uint32_t idx : mesh.indices) ++start[idx + 1];
    for (std::size_t i = 1; i < start.size(); ++i) start[i] += start[i - 1];
    tris.resize(mesh.indices.size());
    std::vector<std::uint32_t> fill(start.begin(), start.end() - 1);
    for (std::size_t t = 0; t < mesh.polygonCount(); ++t) {
      for (std::uint32_t idx : mesh.polygon(t)) tris[fill[idx]++] = static_cast<std::uint32_t>(t);
    }
  }
};

// How a triangle faces the light (facingOf): kOccluder when it can cast a shadow on a pixel that
// is not in attached shadow. Such a pixel's ray starts into the open air, so the first terrain it
// meets, it enters, and it enters through a triangle whose normal points away from the light. Both
// searches take these alone (and, to stay on the safe side of rounding, those within 1e-9 of
// edge-on): the same answers as with every triangle, for a fraction of the work. kFacesAway: the
// light strictly behind it, for attached shadow. The normal is turned up: the frame's +z, or on an
// ellipsoid the body's normal at the triangle's first corner (the DEM's corner order may be
// either way round); `winding` (+1 or -1) says it for a grid, whose triangles all turn alike.
constexpr std::uint8_t kOccluder = 1, kFacesAway = 2;
inline std::uint8_t facingOf(const LocalFrame& frame, std::span<const std::uint32_t> c, const Eigen::Vector3d& light,
                             int winding) {
  const Mesh& mesh = frame.mesh;
  const Eigen::Vector3d& a = mesh.vertices[c[0]];
  const Eigen::Vector3d n = (mesh.vertices[c[1]] - a).cross(mesh.vertices[c[2]] - a);
  const double up = winding != 0 ? winding : frame.body.ellipsoid ? n.dot(frame.upAt(a)) : n.z();
  const double d = up >= 0 ? n.dot(light) : -n.dot(light);
  return static_cast<std::uint8_t>((d <= 0 || d * d <= 1e-18 * n.squaredNorm() ? kOccluder : 0) |
                                   (d < 0 ? kFacesAway : 0));
}

// Attached shadow: the light arrives from below the surface at vertex i. Seen from above (along
// the body's up at i), the light's horizontal direction leaves i through one of its own triangles
// (exactly: the one whose corner sector at i contains that direction); the vertex is in attached
// shadow when the light rises more slowly than that triangle does in that direction, which is
// when the triangle faces away from the light. A light straight up, or a direction leaving the
// terrain (across an edge of the surface), is not attached shadow.
// ring: the triangles around i in increasing order (the first whose sector holds the direction
// decides); closed: they go all the way round, so that when all of them face away, whichever
// holds the direction does. facing: facingOf every triangle.
bool attachedShadow(const LocalFrame& frame, std::span<const std::uint32_t> ring, bool closed, std::uint32_t i,
                    const Eigen::Vector3d& light, const std::uint8_t* facing);

// Runs body(0) .. body(count - 1), each on its own thread (body(0) on this one).
template <class Body>
void inThreads(unsigned count, const Body& body) {
  std::vector<std::thread> pool;
  for (unsigned k = 1; k < count; ++k) pool.emplace_back([&body, k] { body(k); });
  body(0);
  for (auto& t : pool) t.join();
}

}  // namespace qota::shadow
