#include "shadow_facing.hpp"

#include <Eigen/Geometry>
#include <utility>

#include "qota/predicates.hpp"

namespace qota::shadow {

bool attachedShadow(const LocalFrame& frame, std::span<const std::uint32_t> ring, bool closed, std::uint32_t i,
                    const Eigen::Vector3d& light, const std::uint8_t* facing) {
  unsigned away = 0;
  for (const std::uint32_t polygon : ring) away += (facing[polygon] & kFacesAway) != 0;
  if (away == 0) return false;
  const Mesh& mesh = frame.mesh;
  const Eigen::Vector3d& p = mesh.vertices[i];
  // Seen from above: the frame's x, y as they are (exact), or on an ellipsoid the vertex's tangent
  // plane, coordinates relative to the vertex.
  Eigen::Vector3d e1(1, 0, 0), e2(0, 1, 0);
  Point2 p2{p.x(), p.y()}, s2{p.x() + light.x(), p.y() + light.y()};
  if (frame.body.ellipsoid) {
    const Eigen::Vector3d up = frame.upAt(p);
    e1 = up.unitOrthogonal();
    e2 = up.cross(e1);
    p2 = {0, 0};
    s2 = {light.dot(e1), light.dot(e2)};
  }
  if (s2.u == p2.u && s2.v == p2.v) return false;  // the light straight up (or down)
  if (closed && away == ring.size()) return true;
  const auto seen = [&](std::uint32_t k) -> Point2 {
    const Eigen::Vector3d& v = mesh.vertices[k];
    if (!frame.body.ellipsoid) return {v.x(), v.y()};
    const Eigen::Vector3d d = v - p;
    return {d.dot(e1), d.dot(e2)};
  };
  for (const std::uint32_t polygon : ring) {
    const auto t = mesh.polygon(polygon);
    // The other two corners, in counter-clockwise order around i.
    std::uint32_t a = t[0] == i ? t[1] : t[1] == i ? t[2] : t[0];
    std::uint32_t b = t[0] == i ? t[2] : t[1] == i ? t[0] : t[1];
    Point2 a2 = seen(a), b2 = seen(b);
    const int orientation = orient2dSign(p2, a2, b2);
    if (orientation == 0) continue;
    if (orientation < 0) std::swap(a, b), std::swap(a2, b2);
    if (orient2dSign(p2, a2, s2) < 0 || orient2dSign(p2, s2, b2) < 0) continue;  // not this sector
    return (facing[polygon] & kFacesAway) != 0;
  }
  return false;
}

}  // namespace qota::shadow
