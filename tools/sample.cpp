// qota sample: heights under points, as a line-oriented filter (see qota_tools.hpp).
#include <ogr_spatialref.h>

#include <charconv>
#include <fstream>
#include <iostream>
#include <memory>
#include <optional>
#include <string_view>
#include <vector>

#include "qota/dem.hpp"
#include "qota/error.hpp"
#include "qota_tools.hpp"
#include "text_output.hpp"

namespace qota::tools {
namespace {

// "'token' <what>", built by appending (GCC 12 warns falsely on "'" + std::string + "'").
std::string quoted(std::string_view token, std::string_view what) {
  std::string m = "'";
  m += token;
  m += "' ";
  m += what;
  return m;
}

// Splits a line into numbers. Returns an error message, or "" when the line holds 2 or 3 finite
// numbers (or nothing at all: count == 0).
std::string parsePointLine(std::string_view line, double (&values)[3], int& count) {
  count = 0;
  std::size_t i = 0;
  const auto isSep = [](char c) { return c == ' ' || c == '\t' || c == ',' || c == '\r'; };
  while (true) {
    while (i < line.size() && isSep(line[i])) ++i;
    if (i == line.size()) break;
    std::size_t j = i;
    while (j < line.size() && !isSep(line[j])) ++j;
    const std::string_view token = line.substr(i, j - i);
    if (count == 3) return "expected 'x y' or 'x y z', got more than 3 values";
    double v = 0;
    const auto r = std::from_chars(token.data(), token.data() + token.size(), v);
    if (r.ec != std::errc() || r.ptr != token.data() + token.size()) {
      return quoted(token, "is not a number");
    }
    if (!std::isfinite(v)) return quoted(token, "is not a finite number");
    values[count++] = v;
    i = j;
  }
  if (count == 1) return "expected 'x y' or 'x y z', got 1 value";
  return "";
}

std::unique_ptr<OGRCoordinateTransformation> makeTransform(const std::string& srs,
                                                           const DemTerrain& dem) {
  if (srs.empty()) return nullptr;
  if (dem.crsWkt.empty()) {
    throw Error(dem.path + ": the raster has no CRS, so points given in --srs cannot be placed on it");
  }
  OGRSpatialReference from, to;
  if (from.SetFromUserInput(srs.c_str()) != OGRERR_NONE) {
    throw Error("--srs '" + srs + "' is not a coordinate reference system GDAL knows");
  }
  to.importFromWkt(dem.crsWkt.c_str());
  from.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  to.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  std::unique_ptr<OGRCoordinateTransformation> ct(OGRCreateCoordinateTransformation(&from, &to));
  if (!ct) throw Error("--srs '" + srs + "': no transformation to the raster's CRS");
  return ct;
}

}  // namespace

int sample(const SampleOptions& options, std::istream& in, std::ostream& out, std::ostream& err) {
  try {
    const DemTerrain dem = loadDem(options.source);
    const TerrainIndex index(dem.mesh, dem.mapping, options.terrain);
    const auto transform = makeTransform(options.srs, dem);

    std::ifstream file;
    std::istream* input = &in;
    std::string where = "stdin";
    if (!options.inputFile.empty()) {
      file.open(options.inputFile);
      if (!file) throw Error(options.inputFile + ": cannot read");
      input = &file;
      where = options.inputFile;
    }
    std::optional<AtomicFile> outFile;
    std::ostream* output = &out;
    if (!options.outputFile.empty()) {
      outFile.emplace(options.outputFile);
      output = &outFile->stream();
    }

    bool failed = false;
    std::string line;
    for (std::uint64_t lineNo = 1; std::getline(*input, line); ++lineNo) {
      const auto fail = [&](const std::string& token, const std::string& message) {
        *output << token << '\n';
        err << "qota sample: " << where << ':' << lineNo << ": " << message << '\n';
        failed = true;
      };
      double v[3];
      int count = 0;
      if (const std::string problem = parsePointLine(line, v, count); !problem.empty()) {
        fail("error", problem);
        continue;
      }
      if (count == 0) {
        *output << '\n';
        continue;
      }
      double x = v[0], y = v[1];
      if (transform && !transform->Transform(1, &x, &y)) {
        fail("error", "cannot transform (" + formatNumber(v[0]) + ", " + formatNumber(v[1]) +
                          ") from " + options.srs + " to the raster's CRS");
        continue;
      }
      if (!dem.onRaster(x, y)) {
        fail("none", "point (" + formatNumber(x) + ", " + formatNumber(y) + ") is off the raster");
        continue;
      }
      const Eigen::Vector3d m = dem.mapping.toMapped(Eigen::Vector3d(x, y, count == 3 ? v[2] : 0.0));
      const std::optional<Hit> hit =
          count == 3 ? index.below(m.x(), m.y(), m.z()) : index.top(m.x(), m.y());
      if (!hit) {
        *output << "none\n";
        continue;
      }
      *output << formatNumber(hit->height, options.precision);
      if (options.printWorld) {
        for (int k = 0; k < 3; ++k) *output << ' ' << formatNumber(hit->world[k], options.precision);
      }
      *output << '\n';
    }
    if (input->bad()) throw Error(where + ": read error");
    if (outFile) {
      outFile->commit();
    } else {
      output->flush();
    }
    return failed ? 1 : 0;
  } catch (const Error& e) {
    err << "qota sample: " << e.what() << '\n';
    return 2;
  }
}

}  // namespace qota::tools
