// The C++ side of python/bench/bench_numpy.py: the same DEM and the same points (raw float64 x
// then y, written by the Python script), heights through the batch the Python package calls
// (heightsParallel on a Cartesian index of the raster, lon/lat as x, y), timed the same way:
// the median and the spread of 7 runs. Prints "cxx MEDIAN MIN MAX" in seconds.
//   batch_bench DEM POINTS.bin
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <optional>
#include <vector>

#include "qota/dem.hpp"
#include "qota/error.hpp"
#include "qota/terrain.hpp"

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: batch_bench DEM POINTS.bin\n");
    return 2;
  }
  try {
    std::ifstream in(argv[2], std::ios::binary | std::ios::ate);
    if (!in) throw qota::Error(std::string(argv[2]) + ": cannot open");
    const std::size_t n = static_cast<std::size_t>(in.tellg()) / (2 * sizeof(double));
    std::vector<double> xy(2 * n);
    in.seekg(0);
    in.read(reinterpret_cast<char*>(xy.data()), static_cast<std::streamsize>(xy.size() * sizeof(double)));
    const qota::DemTerrain dem = qota::loadDem(argv[1], {.lonLatAsCartesian = true});
    const qota::CartesianIndex index(dem.mesh, dem.mapping);
    const Eigen::Vector3d o = index.mapping().origin();
    std::vector<double> runs;
    std::vector<qota::Point2> pts(n);
    std::vector<std::optional<double>> out(n);
    std::vector<double> heights(n);
    for (int r = 0; r < 7; ++r) {
      // As the Python call: world to index coordinates, the batch, optional to NaN.
      const auto start = std::chrono::steady_clock::now();
      for (std::size_t i = 0; i < n; ++i) pts[i] = {xy[i] - o.x(), xy[n + i] - o.y()};
      index.heightsParallel(pts, out);
      for (std::size_t i = 0; i < n; ++i)
        heights[i] = out[i] ? *out[i] + o.z() : std::numeric_limits<double>::quiet_NaN();
      runs.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    }
    std::vector<double> sorted = runs;
    std::sort(sorted.begin(), sorted.end());
    std::printf("cxx %.6f %.6f %.6f\n", sorted[3], sorted.front(), sorted.back());
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "batch_bench: %s\n", e.what());
    return 2;
  }
}
