// shadow_bench: the shadow mask of a 2000 x 2000 DEM at sun altitudes 30 and 10 degrees, with the
// strip walk (the default) and with the QOTA shadow quadtree, next to the naive ray march measured
// in the same run (from each pixel, step toward the sun one pixel at a time until the ray is
// blocked or leaves the grid). Reports seconds, pixels per second and the ratio, checks that both
// methods give the same mask on every pixel, and checks it against the brute-force oracle on a
// sample of pixels. Flags: --size N (default 2000), --oracle-pixels K (default 60).
#include <Eigen/Geometry>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "qota/shadow.hpp"
#include "qota/synthetic.hpp"

namespace {

using Clock = std::chrono::steady_clock;
using qota::Light;

double seconds(Clock::time_point a, Clock::time_point b) { return std::chrono::duration<double>(b - a).count(); }

// A fractal DEM with 10 m pixels and about 2500 m of relief (20 km across), without CRS.
qota::DemTerrain syntheticDem(int n) {
  const qota::Heightfield hf = qota::fractalHeightfield(n, n, 1.0, 900.0, 7);
  qota::DemTerrain dem;
  dem.path = "synthetic";
  dem.width = dem.height = n;
  dem.geotransform = {0, 10, 0, 0, 0, -10};
  dem.mesh = hf.toMesh();
  return dem;
}

// The naive baseline, single-threaded: one-pixel steps along the sun's direction, the terrain
// height from the same two triangles per cell, read from a plain row-major array of heights (the
// leanest form of the march: nothing but the loop and the heights, 8 bytes a pixel).
// maxHeight: stop a ray once it is above every height (the usual early exit); +inf: none.
std::vector<Light> rayMarch(const qota::LocalFrame& f, const std::vector<double>& heights, const Eigen::Vector3d& d,
                            double maxHeight) {
  const int w = f.width, h = f.height;
  const double* Z = heights.data();
  const double dcol = d.x() / f.pixelSizeX, drow = -d.y() / f.pixelSizeY;
  const double step = 1.0 / std::max(std::fabs(dcol), std::fabs(drow));
  const double dc = dcol * step, dr = drow * step, dz = d.z() * step;
  std::vector<Light> out(heights.size(), Light::Lit);
  for (int r = 0; r < h; ++r) {
    for (int c = 0; c < w; ++c) {
      // The ray's position and height, a step at a time (additions only).
      double cc = c, rr = r, zz = Z[static_cast<std::size_t>(r) * w + c];
      for (;;) {
        cc += dc, rr += dr, zz += dz;
        if (cc < 0 || rr < 0 || cc > w - 1 || rr > h - 1 || zz > maxHeight) break;
        const int c0 = std::min(static_cast<int>(cc), w - 2), r0 = std::min(static_cast<int>(rr), h - 2);
        const double fc = cc - c0, fr = rr - r0;
        const double* p = Z + static_cast<std::size_t>(r0) * w + c0;  // corners p[0], p[1], p[w], p[w + 1]
        const double z = fr > fc ? p[0] + fr * (p[w] - p[0]) + fc * (p[w + 1] - p[w])
                                 : p[0] + fc * (p[1] - p[0]) + fr * (p[w + 1] - p[1]);
        if (z > zz) {
          out[static_cast<std::size_t>(r) * w + c] = Light::Shadow;
          break;
        }
      }
    }
  }
  return out;
}

// The oracle for one pixel: attached shadow from its own triangles (a point a millionth of a pixel
// toward the light below the surface), cast shadow from any other triangle the ray meets.
bool oracleShadow(const qota::LocalFrame& f, std::size_t i, const Eigen::Vector3d& light) {
  const auto& v = f.mesh.vertices;
  const Eigen::Vector3d q = v[i] + 1e-6 * f.pixelSizeX / light.head<2>().norm() * light;
  for (std::size_t p = 0; p < f.mesh.polygonCount(); ++p) {
    const auto t = f.mesh.polygon(p);
    const bool own = t[0] == i || t[1] == i || t[2] == i;
    if (own) {
      const Eigen::Vector2d a = v[t[0]].head<2>(), b = v[t[1]].head<2>(), c = v[t[2]].head<2>(), x = q.head<2>();
      const double area = (b - a).x() * (c - a).y() - (b - a).y() * (c - a).x();
      const double wa = ((b - x).x() * (c - x).y() - (b - x).y() * (c - x).x()) / area;
      const double wb = ((c - x).x() * (a - x).y() - (c - x).y() * (a - x).x()) / area;
      const double wc = 1 - wa - wb;
      if (wa >= 0 && wb >= 0 && wc >= 0 && q.z() < wa * v[t[0]].z() + wb * v[t[1]].z() + wc * v[t[2]].z()) return true;
      continue;
    }
    const Eigen::Vector3d e1 = v[t[1]] - v[t[0]], e2 = v[t[2]] - v[t[0]], pv = light.cross(e2);
    const double det = e1.dot(pv);
    if (det == 0) continue;
    const Eigen::Vector3d tv = v[i] - v[t[0]], qv = tv.cross(e1);
    const double a = tv.dot(pv) / det, b = light.dot(qv) / det, dist = e2.dot(qv) / det;
    if (a >= 0 && b >= 0 && a + b <= 1 && dist > 0) return true;
  }
  return false;
}

}  // namespace

int main(int argc, char** argv) {
  int n = 2000, oraclePixels = 60;
  for (int i = 1; i < argc; ++i) {
    const bool valued = i + 1 < argc;
    if (valued && !std::strcmp(argv[i], "--size")) {
      n = std::atoi(argv[++i]);
    } else if (valued && (!std::strcmp(argv[i], "--oracle-pixels") || !std::strcmp(argv[i], "--oracle-cells"))) {
      oraclePixels = std::atoi(argv[++i]);
    } else {
      std::fprintf(stderr, "shadow_bench: unknown argument %s (--size N, --oracle-pixels N)\n", argv[i]);
      return 2;
    }
  }
  if (n < 16 || oraclePixels < 0) {
    std::fprintf(stderr, "shadow_bench: --size at least 16, --oracle-pixels at least 0\n");
    return 2;
  }
  const qota::DemTerrain dem = syntheticDem(n);
  const qota::LocalFrame frame = qota::localFrame(dem, false, 10.0);
  std::vector<double> heights(frame.pixelCount());
  for (std::size_t i = 0; i < heights.size(); ++i) heights[i] = frame.mesh.vertices[i].z();
  const double pixels = static_cast<double>(n) * n;
  std::printf("shadow_bench: %d x %d DEM (%.0f pixels, %zu triangles), relief %.0f m, %u cores\n", n, n, pixels,
              dem.mesh.polygonCount(), frame.maxHeight - frame.minHeight, std::thread::hardware_concurrency());
  std::printf("%-6s %-22s %10s %14s %9s %10s %12s\n", "alt", "method", "seconds", "pixels/s", "vs march", "shadow %",
              "agree march");
  std::printf(
      "(vs march: the naive march's time over this method's; the march with the max-height\n"
      " exit gives the same mask sooner and is the stricter baseline)\n");
  for (double alt : {30.0, 10.0}) {
    // Not 135 exactly: then rays from pixel centres run along the triangle diagonals, a degenerate
    // case the floating-point oracle cannot decide (qota decides it exactly).
    const Eigen::Vector3d light = frame.towardSun({137.3, alt});
    auto t0 = Clock::now();
    const auto capped = rayMarch(frame, heights, light, frame.maxHeight);
    auto t1 = Clock::now();
    const double cappedS = seconds(t0, t1);
    t0 = Clock::now();
    const auto march = rayMarch(frame, heights, light, INFINITY);
    t1 = Clock::now();
    const double marchS = seconds(t0, t1);
    if (capped != march) std::printf("warning: the two ray marches disagree\n");
    std::printf("%-6.0f %-22s %10.3f %14.0f %9.2f %10s %12s\n", alt, "march, max-height exit", cappedS,
                pixels / cappedS, marchS / cappedS, "", "");
    std::size_t marchShadow = 0;
    for (Light l : march) marchShadow += l == Light::Shadow;
    std::printf("%-6.0f %-22s %10.3f %14.0f %9s %10.2f %12s\n", alt, "naive ray march (1 th)", marchS, pixels / marchS,
                "1.00", 100.0 * marchShadow / pixels, "-");
    std::vector<Light> stripsMask;
    for (const auto search : {qota::ShadowSearch::Strips, qota::ShadowSearch::Quadtree}) {
      for (unsigned threads : {1u, 0u}) {
        t0 = Clock::now();
        const auto mask = qota::shadowMask(frame, light, {}, {}, threads, search);
        t1 = Clock::now();
        const double s = seconds(t0, t1);
        std::size_t shadow = 0, agree = 0;
        for (std::size_t i = 0; i < mask.size(); ++i) {
          shadow += mask[i] == Light::Shadow;
          agree += mask[i] == march[i];
        }
        const bool walk = search == qota::ShadowSearch::Strips;
        const std::string name =
            std::string(walk ? "qota strips" : "qota quadtree") + (threads == 1 ? " (1 thread)" : " (all cores)");
        std::printf("%-6.0f %-22s %10.3f %14.0f %9.2f %10.2f %11.3f%%\n", alt, name.c_str(), s, pixels / s, marchS / s,
                    100.0 * shadow / pixels, 100.0 * agree / pixels);
        if (walk && threads == 0) stripsMask = mask;
        if (!walk && threads == 0) {
          std::printf("%-6.0f strips and quadtree masks identical on every pixel: %s\n", alt,
                      mask == stripsMask ? "yes" : "NO");
        }
      }
    }
    if (oraclePixels > 0) {
      std::mt19937_64 rng(static_cast<std::uint64_t>(alt));
      std::uniform_int_distribution<std::size_t> pick(0, stripsMask.size() - 1);
      int same = 0;
      for (int k = 0; k < oraclePixels; ++k) {
        const std::size_t i = pick(rng);
        const bool ok = (stripsMask[i] == Light::Shadow) == oracleShadow(frame, i, light);
        same += ok;
        if (!ok) {
          std::printf("  differs at pixel %zu (col %zu, row %zu): qota %s\n", i, i % n, i / n,
                      stripsMask[i] == Light::Shadow ? "shadow" : "lit");
        }
      }
      std::printf("%-6.0f oracle check: %d of %d random pixels identical to the brute force\n", alt, same,
                  oraclePixels);
    }
  }
  return 0;
}
