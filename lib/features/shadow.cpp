#include "qota/shadow.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <optional>
#include <span>
#include <thread>

#include "qota/error.hpp"
#include "shadow_facing.hpp"
#include "shadow_strips.hpp"

namespace qota {

using shadow::attachedShadow;
using shadow::facingOf;
using shadow::HorizonStrips;
using shadow::inThreads;
using shadow::kFacesAway;
using shadow::kOccluder;
using shadow::VertexStar;

double shadowReach(const LocalFrame& frame, const Eigen::Vector3d& towardLight) {
  const Eigen::Vector3d d = towardLight.normalized();
  const double horizontal = d.head<2>().norm();
  if (d.z() <= 0) return INFINITY;
  return (frame.maxHeight - frame.minHeight) * horizontal / d.z();
}

std::vector<Light> shadowMask(const LocalFrame& frame, const Eigen::Vector3d& towardLight, const IndexOptions& options,
                              const Progress& progress, unsigned threadCount, ShadowSearch search,
                              std::optional<PixelWindow> testOnly) {
  const auto& vertices = frame.mesh.vertices;
  const std::size_t pixelCount = frame.pixelCount();
  if (frame.valid.size() != pixelCount || vertices.size() < pixelCount) {
    throw Error("shadow mask: the frame's pixels and vertices do not match its size");
  }
  const PixelWindow test = testOnly.value_or(PixelWindow{0, 0, frame.width, frame.height});
  if (test.col < 0 || test.row < 0 || test.width < 0 || test.height < 0 || test.col + test.width > frame.width ||
      test.row + test.height > frame.height) {
    throw Error("shadow mask: the pixels to test are not all in the frame");
  }
  const std::size_t testCount = test.pixelCount();
  const auto tested = [&](std::size_t i) {
    const auto c = static_cast<int>(i % frame.width), r = static_cast<int>(i / frame.width);
    return c >= test.col && c < test.col + test.width && r >= test.row && r < test.row + test.height;
  };
  std::vector<Light> out(pixelCount, Light::NoData);
  const auto report = [&](double done, const char* message) {
    if (progress && !progress(done, message)) throw Error("shadow computation cancelled");
  };
  if (!towardLight.allFinite() || towardLight.squaredNorm() == 0) {
    throw Error("light direction must be a nonzero finite vector");
  }
  const Eigen::Vector3d light = towardLight.normalized();
  if (!frame.body.ellipsoid && light.z() <= 0) {
    // A flat frame with the light at or below the horizon: no direct light anywhere.
    for (std::size_t i = 0; i < pixelCount; ++i) {
      if (frame.valid[i] && tested(i)) out[i] = Light::Shadow;
    }
    report(1.0, "light below the horizon");
    return out;
  }
  if (frame.body.ellipsoid && std::asin(std::clamp(light.z(), -1.0, 1.0)) * 180 / M_PI < -frame.horizonSlack()) {
    // Below every pixel's horizon by more than the dip from the highest terrain: every ray enters
    // the body, which shades the pixel whatever the terrain (sunCanLight's argument, sunlight.hpp).
    for (std::size_t i = 0; i < pixelCount; ++i) {
      if (frame.valid[i] && tested(i)) out[i] = Light::Shadow;
    }
    report(1.0, "light below every pixel's horizon");
    return out;
  }

  // The strips need a horizontal direction to the light (not straight overhead), and keep their
  // ranges in floats: coordinates far beyond any planet's (localFrame refuses heights beyond
  // 1e9 m; a frame made by hand may hold anything) take the quadtree instead.
  double extent = 0;
  for (const Eigen::Vector3d& v : vertices) extent = std::max(extent, v.cwiseAbs().maxCoeff());
  const bool useStrips = search == ShadowSearch::Strips && light.head<2>().norm() > 1e-6 && extent < 1e30;
  const unsigned threads = threadCount ? threadCount : std::max(1u, std::min(8u, std::thread::hardware_concurrency()));
  // The light's direction of travel is the "gravity" of the shadow quadtree's frame: "above" a
  // point means toward the light. The strips decide their candidates in the same frame.
  const CartesianMapping mapping(-light);
  // The triangles around each vertex: arithmetic on localFrame's own grid, else a table.
  const bool gridMesh = frame.gridMesh && frame.grid.width() == frame.width && frame.grid.height() == frame.height &&
                        vertices.size() == frame.grid.vertexCount() &&
                        frame.mesh.polygonCount() == frame.grid.triangleCount();
  std::optional<VertexStar> star;
  if (!gridMesh) star.emplace(frame.mesh);
  // On an ellipsoid a grid's triangles all turn alike (facingOf); else each is looked at.
  const int winding = frame.body.ellipsoid && gridMesh ? frame.gridWinding : 0;

  // Two passes over the pixels, each shared out to `workers` threads in groups (the calling thread
  // reports progress), after every triangle's facing is known: attached shadow (and the body's
  // own shadow) by rows, reading each vertex's ring in memory order; then cast shadow for the
  // pixels still lit, by rows through the quadtree or by strips through the strips (each strip's
  // pixels in row order, so nearly in order of a: consecutive searches read the same few cache
  // lines of the same strip).
  const auto width = static_cast<std::size_t>(frame.width);
  std::atomic<std::size_t> pixelsDone{0};
  std::atomic<bool> stop{false};
  const auto inParallel = [&](unsigned workers, std::size_t groups, const auto& pixelsOf, const auto& body) {
    std::atomic<std::size_t> next{0};
    const auto work = [&](bool reporter) {
      for (std::size_t g; !stop && (g = next++) < groups;) {
        body(g);
        const std::size_t done = pixelsDone += pixelsOf(g);
        const double fraction =
            static_cast<double>(done) / static_cast<double>(2 * std::max<std::size_t>(1, testCount));
        if (reporter && progress && !progress(0.3 + 0.7 * fraction, "testing pixels")) stop = true;
      }
    };
    inThreads(workers, [&](unsigned k) { work(k == 0); });
  };
  // Rows of the pixels tested: test.row + r, columns [first, last).
  const std::size_t first = static_cast<std::size_t>(test.col), last = first + static_cast<std::size_t>(test.width);
  const auto rowPixels = [&](std::size_t) { return last - first; };
  std::vector<std::uint8_t> facing;  // facingOf every triangle
  const BodyRays bodyRays(frame, light);
  const auto attachedPass = [&](unsigned workers) {
    inParallel(workers, static_cast<std::size_t>(test.height), rowPixels, [&](std::size_t k) {
      const std::size_t r = k + static_cast<std::size_t>(test.row);
      for (std::size_t i = r * width + first; i < r * width + last; ++i) {
        if (!frame.valid[i]) continue;
        std::uint32_t grid[RasterGrid::kMaxRing];
        bool closed = false;
        const std::span<const std::uint32_t> ring =
            gridMesh ? std::span<const std::uint32_t>(
                           grid, static_cast<std::size_t>(frame.grid.ring(
                                     static_cast<int>(r), static_cast<int>(i - r * width), grid, closed)))
                     : std::span<const std::uint32_t>(star->tris.data() + star->start[i],
                                                      star->start[i + 1] - star->start[i]);
        const bool shadow = attachedShadow(frame, ring, closed, static_cast<std::uint32_t>(i), light, facing.data()) ||
                            (frame.body.ellipsoid && bodyRays.entersBody(vertices[i]));
        out[i] = shadow ? Light::Shadow : Light::Lit;
      }
    });
  };

  if (!useStrips) {
    report(0.0, "building the shadow quadtree");
    Mesh occluders;
    occluders.vertices = frame.mesh.vertices;
    facing.resize(frame.mesh.polygonCount());
    for (std::size_t t = 0; t < frame.mesh.polygonCount(); ++t) {
      const auto c = frame.mesh.polygon(t);
      facing[t] = facingOf(frame, c, light, winding);
      if (facing[t] & kOccluder) occluders.addTriangle(c[0], c[1], c[2]);
    }
    report(0.3, "testing pixels");
    attachedPass(threads);
    if (occluders.polygonCount() > 0) {
      const CartesianIndex index(occluders, mapping, options);
      inParallel(threads, static_cast<std::size_t>(test.height), rowPixels, [&](std::size_t k) {
        const std::size_t r = k + static_cast<std::size_t>(test.row);
        for (std::size_t i = r * width + first; i < r * width + last; ++i) {
          if (out[i] != Light::Lit) continue;
          const Eigen::Vector3d m = mapping.toMapped(vertices[i]);
          if (index.occludedAbove(m.x(), m.y(), m.z(), static_cast<std::uint32_t>(i))) out[i] = Light::Shadow;
        }
      });
    }
  } else {
    report(0.0, "sorting the occluders into strips");
    const HorizonStrips strips(frame, light, std::min(frame.pixelSizeX, frame.pixelSizeY), facing, threads, winding);
    report(0.3, "testing pixels");
    attachedPass(threads);
    // The tested pixels (k-th in row order: pixel testPixel(k)) by strip.
    const auto testPixel = [&](std::size_t k) {
      return (k / (last - first) + static_cast<std::size_t>(test.row)) * width + first + k % (last - first);
    };
    std::vector<std::uint32_t> stripOf(testCount), order(testCount);
    std::vector<std::uint64_t> start(strips.stripCount() + 2, 0);  // the last: pixels in none
    for (std::size_t k = 0; k < testCount; ++k) {
      stripOf[k] = static_cast<std::uint32_t>(strips.stripOf(vertices[testPixel(k)]));
      ++start[stripOf[k] + 1];
    }
    for (std::size_t g = 1; g < start.size(); ++g) start[g] += start[g - 1];
    std::vector<std::uint64_t> fill(start.begin(), start.end() - 1);
    for (std::size_t k = 0; k < testCount; ++k) order[fill[stripOf[k]]++] = static_cast<std::uint32_t>(testPixel(k));
    inParallel(
        threads, start.size() - 1, [&](std::size_t g) { return start[g + 1] - start[g]; },
        [&](std::size_t g) {
          std::uint64_t hint = 0;
          for (std::uint64_t k = start[g]; k < start[g + 1]; ++k) {
            if (k + 8 < start[g + 1]) {  // a strip's pixels are a row apart in memory
              __builtin_prefetch(&vertices[order[k + 8]]);
              __builtin_prefetch(&out[order[k + 8]]);
            }
            const std::uint32_t i = order[k];
            if (out[i] != Light::Lit) continue;
            const Eigen::Vector3d m = mapping.toMapped(vertices[i]);
            const auto occludes = [&](std::uint32_t t) {
              // A pixel's own triangles meet its ray at the pixel itself: never an occluder.
              const auto c = frame.mesh.polygon(t);
              if (c[0] == i || c[1] == i || c[2] == i) return false;
              return mappedTriangleAbove(mapping.toMapped(vertices[c[0]]), mapping.toMapped(vertices[c[1]]),
                                         mapping.toMapped(vertices[c[2]]), m.x(), m.y(), m.z());
            };
            if (strips.anyAlong(vertices[i], hint, occludes)) out[i] = Light::Shadow;
          }
        });
  }
  if (stop) throw Error("shadow computation cancelled");
  report(1.0, "done");
  return out;
}

}  // namespace qota
