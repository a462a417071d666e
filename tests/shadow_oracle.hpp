// The brute-force shadow oracle: every triangle tested by plain floating point, no index, no
// strips, none of qota's shadow code (only the frame's vertices, made by localFrame).
#pragma once

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <optional>
#include <vector>

#include "qota/shadow.hpp"

namespace qota::test {

// The terrain's height under (x, y) seen from above, by testing every triangle (none: NaN).
inline double surfaceAt(const qota::LocalFrame& f, double x, double y) {
  const auto& v = f.mesh.vertices;
  for (std::size_t p = 0; p < f.mesh.polygonCount(); ++p) {
    const auto t = f.mesh.polygon(p);
    const Eigen::Vector2d a = v[t[0]].head<2>(), b = v[t[1]].head<2>(), c = v[t[2]].head<2>();
    const double area = (b - a).x() * (c - a).y() - (b - a).y() * (c - a).x();
    const Eigen::Vector2d q(x, y);
    const double wa = ((b - q).x() * (c - q).y() - (b - q).y() * (c - q).x()) / area;
    const double wb = ((c - q).x() * (a - q).y() - (c - q).y() * (a - q).x()) / area;
    const double wc = 1 - wa - wb;
    if (wa >= 0 && wb >= 0 && wc >= 0) return wa * v[t[0]].z() + wb * v[t[1]].z() + wc * v[t[2]].z();
  }
  return NAN;
}

// The oracle for one valid pixel i: attached shadow when a point a millionth of a pixel toward the
// light lies below the surface there; cast shadow when the ray from the vertex toward the light
// meets a triangle that does not have that vertex as a corner (Moller-Trumbore, t > 0). A flat
// frame's rule ("up" is +z).
inline qota::Light bruteForcePixel(const qota::LocalFrame& f, std::size_t i, const Eigen::Vector3d& light) {
  using qota::Light;
  const auto& v = f.mesh.vertices;
  const double eps = 1e-6 * f.pixelSizeX / std::max(1e-9, light.head<2>().norm());
  const Eigen::Vector3d q = v[i] + eps * light;
  if (light.head<2>().norm() > 0 && q.z() < surfaceAt(f, q.x(), q.y())) return Light::Shadow;
  for (std::size_t p = 0; p < f.mesh.polygonCount(); ++p) {
    const auto t = f.mesh.polygon(p);
    if (t[0] == i || t[1] == i || t[2] == i) continue;
    const Eigen::Vector3d e1 = v[t[1]] - v[t[0]], e2 = v[t[2]] - v[t[0]];
    const Eigen::Vector3d pv = light.cross(e2);
    const double det = e1.dot(pv);
    if (det == 0) continue;
    const Eigen::Vector3d tv = v[i] - v[t[0]];
    const double a = tv.dot(pv) / det;
    const Eigen::Vector3d qv = tv.cross(e1);
    const double b = light.dot(qv) / det;
    const double dist = e2.dot(qv) / det;
    if (a >= 0 && b >= 0 && a + b <= 1 && dist > 0) return Light::Shadow;
  }
  return Light::Lit;
}

// The oracle with the sun turned by 1e-7 degrees either way: its answer where the two agree,
// else nothing (a pixel on the knife edge). bruteForcePixel's floating-point ray test is not
// watertight: a sun along a grid axis or a pixel diagonal sends its rays exactly along shared
// edges, where they can slip between the triangles; the answer at the sun itself lies between
// the turned ones.
inline std::optional<qota::Light> bruteForcePixelTurned(const qota::LocalFrame& f, std::size_t i,
                                                        const qota::SunPosition& sun) {
  const qota::Light before = bruteForcePixel(f, i, f.towardSun({sun.azimuth - 1e-7, sun.altitude}));
  if (before != bruteForcePixel(f, i, f.towardSun({sun.azimuth + 1e-7, sun.altitude}))) return std::nullopt;
  return before;
}

// The oracle on every pixel (NoData where the frame has no data).
inline std::vector<qota::Light> bruteForceMask(const qota::LocalFrame& f, const Eigen::Vector3d& light) {
  std::vector<qota::Light> out(f.pixelCount(), qota::Light::NoData);
  for (std::size_t i = 0; i < f.pixelCount(); ++i) {
    if (f.valid[i]) out[i] = bruteForcePixel(f, i, light);
  }
  return out;
}

}  // namespace qota::test
