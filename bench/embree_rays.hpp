// Vertical rays down (-z) through an Embree scene, one at a time (rtcIntersect1) and in packets
// of 16 (rtcIntersect16): what the Embree side of embree_bench and tin_bench times.
#pragma once

#include <embree3/rtcore.h>

#include <algorithm>
#include <cmath>
#include <cstddef>

namespace bench {

// The height where the ray down from (u, v, z) first meets the scene; NaN for none.
inline float rayDown(RTCScene scene, double u, double v, float z) {
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  RTCRayHit rh{};
  rh.ray.org_x = static_cast<float>(u), rh.ray.org_y = static_cast<float>(v), rh.ray.org_z = z;
  rh.ray.dir_z = -1.0f;
  rh.ray.tnear = 0, rh.ray.tfar = INFINITY, rh.ray.mask = 0xffffffffu;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(scene, &ctx, &rh);
  return rh.hit.geomID == RTC_INVALID_GEOMETRY_ID ? NAN : z - rh.ray.tfar;
}

// rayDown for rays i = 0..n-1, sixteen a packet: u(i), v(i) and z(i) give ray i, out(i, height)
// takes its answer.
template <class U, class V, class Z, class Out>
void raysDown16(RTCScene scene, std::size_t n, U&& u, V&& v, Z&& z, Out&& out) {
  alignas(64) RTCRayHit16 rh;
  alignas(64) int valid[16];
  for (std::size_t g = 0; g < n; g += 16) {
    const std::size_t m = std::min<std::size_t>(16, n - g);
    for (std::size_t i = 0; i < 16; ++i) {
      const std::size_t k = g + std::min(i, m - 1);
      valid[i] = i < m ? -1 : 0;
      rh.ray.org_x[i] = static_cast<float>(u(k)), rh.ray.org_y[i] = static_cast<float>(v(k));
      rh.ray.org_z[i] = z(k);
      rh.ray.dir_x[i] = 0, rh.ray.dir_y[i] = 0, rh.ray.dir_z[i] = -1;
      rh.ray.tnear[i] = 0, rh.ray.tfar[i] = INFINITY, rh.ray.mask[i] = 0xffffffffu;
      rh.ray.time[i] = 0, rh.ray.flags[i] = 0;
      rh.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
    }
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    rtcIntersect16(valid, scene, &ctx, &rh);
    for (std::size_t i = 0; i < m; ++i) {
      out(g + i, rh.hit.geomID[i] == RTC_INVALID_GEOMETRY_ID ? NAN : z(g + i) - rh.ray.tfar[i]);
    }
  }
}

}  // namespace bench
