// qota sample's private parts (tools/ only): the queries a surface answers and the line loop that
// reads them (sample_lines.cpp), shared with the surfaces that answer them (sample.cpp).
#pragma once

#include <gdal_priv.h>
#include <ogr_spatialref.h>

#include <Eigen/Core>
#include <exception>
#include <functional>
#include <memory>
#include <istream>
#include <mutex>
#include <optional>
#include <ostream>
#include <span>
#include <string>

#include "qota/batch.hpp"
#include "qota_tools.hpp"

namespace qota::tools::sampling {

// One answer of a surface: the height and world point, or nothing; `problem` set when the point
// is outside the surface's domain (printed as `token`, with the message on stderr).
struct Answer {
  std::optional<double> height;
  Eigen::Vector3d world = Eigen::Vector3d::Zero();
  std::string token, problem;
};
inline Answer outside(const char* token, std::string problem) { return {std::nullopt, {}, token, std::move(problem)}; }

// A point of a line: (x, y) in the input's order after -w and --srs, z the query height.
struct Query {
  double x = 0, y = 0, z = 0;
};

// A height from an integer raster as qota sample prints it without -p: rounded to a millionth of
// its unit (far below any DEM's accuracy, far above the interpolation's rounding: a few units in
// the last place of the height, 1e-12 of it).
inline double withoutNoise(double h) {
  if (!(h > -1e9 && h < 1e9)) return h;
  // (half away from zero through an integer conversion: std::round is a library call here)
  const double k = h * 1e6;
  return static_cast<double>(static_cast<long long>(k + (k < 0 ? -0.5 : 0.5))) / 1e6;
}

// The terrain of options.source with its queries, answered a batch at a time (answers[i] for
// queries[i], each set whole; hasZ: every query has its height). Called on one thread; it may
// use several.
using Surface = std::function<void(std::span<const Query> queries, bool hasZ, std::span<Answer> answers)>;

// Runs work(lo, hi) over [0, n) on every core (slices of at least minPerThread); an exception in
// a slice is rethrown here (a worker thread must not end the process).
template <class Work>
void inParallel(std::size_t n, std::size_t minPerThread, Work&& work) {
  std::exception_ptr failure;
  std::mutex lock;
  batch::inSlices(n, 0, minPerThread, [&](std::size_t lo, std::size_t hi) {
    try {
      work(lo, hi);
    } catch (...) {
      const std::lock_guard<std::mutex> hold(lock);
      if (!failure) failure = std::current_exception();
    }
  });
  if (failure) std::rethrow_exception(failure);
}

// Reads `in` to its end, a line at a time as qota sample's help says, answering the points on
// `surface` (placed by `transform` from --srs first, when given) and writing one line per input
// line to `out`; a failed line's message goes to `err` (the first 20, then a count). `where`
// names the input in messages. integerSource: the heights are interpolated from whole numbers
// (an integer raster), so the shortest form (no -p) prints them rounded to a millionth of the
// unit, which drops the last-bit noise of the interpolation (4367.000000000034 prints 4367).
// Returns whether any line failed.
// A vector layer of points (any OGR format with geometries; a CSV whose columns name x and y or
// hold WKT) opened from options.inputFile, or null when the file is lines of text.
std::unique_ptr<GDALDataset> openPointLayer(const SampleOptions& options);
// Samples the layer's points on `surface` (transformed from the layer's CRS, or --srs, to
// sourceWkt) and writes them with every field and a height field to options.outputFile, staged.
// A failed feature's message goes to `err` (the first 20, then a count). Returns whether any
// feature failed (not a point, off the source).
bool sampleLayer(const SampleOptions& options, GDALDataset& in, const Surface& surface, const std::string& sourceWkt,
                 bool integerSource, std::ostream& err);

bool readLines(const SampleOptions& options, const Surface& surface, OGRCoordinateTransformation* transform,
               std::istream& in, std::ostream& out, std::ostream& err, const std::string& where,
               bool integerSource = false);

}  // namespace qota::tools::sampling
