// What qota's big steps cost in memory, so that a job too large for the machine is refused before
// anything large is allocated, and the refusal can be trusted: each figure is the most the step
// was measured to add (peak resident memory, scripts/memory.sh prints both side by side), per
// vertex and per triangle, with a margin. The tools print their peak beside the estimate.
#pragma once

#include <cstdint>
#include <string>

namespace qota::memory {

struct PerItem {
  std::uint64_t perVertex = 0, perTriangle = 0;
  std::uint64_t bytes(std::uint64_t vertices, std::uint64_t triangles) const {
    return vertices * perVertex + triangles * perTriangle;
  }
  // Steps that run together (their memory held at once).
  friend constexpr PerItem operator+(PerItem a, PerItem b) {
    return {a.perVertex + b.perVertex, a.perTriangle + b.perTriangle};
  }
};

// The process before any terrain: the C++ runtime, GDAL, PROJ, Assimp and their caches (measured
// 56 MB for a one-pixel raster).
constexpr std::uint64_t kProcessBase = 80ull << 20;
// A raster read into a terrain (loadDem): the vertices, the pixels read as doubles while they are
// placed, the triangles' indices.
constexpr PerItem kDemMesh{36, 13};
// A raster read as heights alone (DemOptions::vertices false): the heights as doubles.
constexpr PerItem kDemHeights{10, 0};
// A CartesianIndex with its quadtree, at its build's peak (records, pending list, Morton keys,
// references, the triangles' boxes). Measured 203 to 247 bytes a triangle (Rainier's 1201 x 1201
// and 500 x 500 of it, Mount St. Helens; the peak varies from run to run by the build's threads).
constexpr PerItem kCartesianIndex{40, 270};
// A CartesianIndex on a regular grid answering heights only: the lean grid, no tree (qota sample).
constexpr PerItem kGridIndex{40, 80};
// A curved index (spherical, geodetic, cylindrical) with its quadtree. Measured up to 313.
constexpr PerItem kCurvedIndex{40, 360};
// A shadow mask: the frame's mesh, the facing, the strips, the cell order. Measured up to 53.
constexpr PerItem kShadow{40, 70};
// Lines of sight (viewsheds, point lights): the frame, the heights in metres, the blocking
// triangles' mesh and their CartesianIndex, and each triangle's square both ways (8 bytes, for
// the blocker guess). Measured 300 MB for 556 x 556 pixels, with the process; 2.28 GB for
// 2000 x 2000 (bench/viewshed_bench.sh), where this says 2.91 GiB.
constexpr PerItem kLinesOfSight{100, 300};
// A viewshed by the sweep (a flat frame; viewshed_sweep.hpp), which keeps no vertices, triangles
// or quadtree: the heights in metres, which pixels have data, the verdicts, the classes written.
// With the heights read (kDemHeights), measured 21 bytes a pixel (bench/viewshed_bench.sh's DEM
// and a 6000 x 6000 one like it); with a PNG preview over a hillshade 60 (kPreview adds the
// difference), counting many observers 36 (kCounts), and which observers see each pixel 49 (kWhich
// more).
constexpr PerItem kSweptLinesOfSight{16, 0};
// Lines of sight walked over the squares under them, with no quadtree (viewsheds on an ellipsoid,
// viewshed.cpp): the frame's points, the heights in metres, each point's height in the
// observer's model, the verdicts. With the heights read (kDemHeights), measured 42 bytes a pixel
// (bench/viewshed_bench.sh's DEM, and the same at 10 m: 6000 x 6000).
constexpr PerItem kWalkedLinesOfSight{40, 0};
// A point light walked (qota shadow --light-point): the same with the frame's triangles and how
// each faces the light, beside the shadow tool's own mesh and frame (kDemMesh, read). Measured 162
// to 166 bytes a pixel in all (the two DEMs above).
constexpr PerItem kWalkedLight{120, 0};
constexpr PerItem kPreview{45, 0};
constexpr PerItem kCounts{18, 0};
constexpr PerItem kWhich{16, 0};

// Memory available to this process for new work, in bytes: the least of MemAvailable (else
// physical memory), what the memory control group (a container's limit) and ulimit -v still
// allow, and what setLimit leaves; 0 when none is known.
std::uint64_t availableBytes();
// A budget for the whole process (0: none): availableBytes() reports at most `bytes` minus the
// resident memory, so jobs are refused or stopped as if the machine had that much.
void setLimit(std::uint64_t bytes);
// This process's peak resident memory so far (VmHWM), in bytes; 0 when unknown.
std::uint64_t peakBytes();
// This process's resident memory now (VmRSS), in bytes; 0 when unknown.
std::uint64_t residentBytes();
// Gives memory the process freed back to the system (glibc keeps it in its arenas otherwise): a
// job of many steps that each allocate and free much (hours of sunlight) calls it between them,
// so that its peak is one step's, not the sum of what the arenas kept.
void releaseFreedMemory();
// "1.23 GiB".
std::string gib(std::uint64_t bytes);
// Throws qota::Error when `cost` for these vertices and triangles exceeds the memory available
// now; `what` names the job ("terrain of 3 polygons").
void require(const std::string& what, const PerItem& cost, std::uint64_t vertices, std::uint64_t triangles);

}  // namespace qota::memory
