// qota sample: heights under points, as a line-oriented filter (see qota_tools.hpp).
#include <ogr_spatialref.h>

#include <charconv>
#include <fstream>
#include <functional>
#include <type_traits>
#include <iostream>
#include <memory>
#include <optional>
#include <string_view>
#include <vector>

#include "qota/curved.hpp"
#include "qota/dem.hpp"
#include "qota/error.hpp"
#include "index_source.hpp"
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

// One answer of a surface: the hit, or nothing; `problem` set when the point is outside the
// surface's domain (printed as `token` with the message on stderr).
struct Answer {
  std::optional<Hit> hit;
  std::string token, problem;
};
// (x, y) in the input's order after -w; z: the query height, or null for the top surface.
using Surface = std::function<Answer(double x, double y, const double* z)>;

// The terrain of options.source (a tree file, or a raster or mesh in options.mapping), with its
// query. The index lives in the returned closure.
Surface openSurface(const SampleOptions& options) {
  SourceOptions so;
  so.source = options.source;
  so.mapping = options.mapping;
  so.radius = options.radius;
  so.length = options.length;
  so.terrain = options.terrain;
  auto tree = std::make_shared<TreeFile>(openIndex(so));
  if (const TerrainIndex* index = std::get_if<TerrainIndex>(&tree->index)) {
    // The raster's footprint and CRS, when the source was a raster.
    auto grid = std::make_shared<DemTerrain>();
    grid->path = tree->source.path.empty() ? options.source : tree->source.path;
    grid->crsWkt = tree->source.crsWkt;
    grid->width = tree->source.width, grid->height = tree->source.height;
    grid->geotransform = tree->source.geotransform;
    std::shared_ptr<OGRCoordinateTransformation> transform = makeTransform(options.srs, *grid);
    return [tree, index, grid, transform, srs = options.srs](double x0, double y0, const double* z) {
      double x = x0, y = y0;
      if (transform && !transform->Transform(1, &x, &y)) {
        return Answer{std::nullopt, "error",
                      "cannot transform (" + formatNumber(x0) + ", " + formatNumber(y0) +
                          ") from " + srs + " to the raster's CRS"};
      }
      if (grid->width > 0 && !grid->onRaster(x, y)) {
        return Answer{std::nullopt, "none",
                      "point (" + formatNumber(x) + ", " + formatNumber(y) + ") is off the raster"};
      }
      const Eigen::Vector3d m = index->mapping().toMapped(Eigen::Vector3d(x, y, z ? *z : 0.0));
      return Answer{z ? index->below(m.x(), m.y(), m.z()) : index->top(m.x(), m.y()), "", ""};
    };
  }
  if (!options.srs.empty()) {
    throw Error("--srs applies to the cartesian mapping only; the " +
                std::string(mappingNameOf(tree->index)) +
                " mapping reads longitude/latitude (or angle/axial) coordinates");
  }
  // The curved mappings share their query; only the domain check differs.
  return std::visit(
      [&](const auto& index) -> Surface {
        const bool latitude = !std::is_same_v<std::decay_t<decltype(index)>, CylindricalIndex>;
        return [tree, &index, latitude](double u, double v, const double* z) {
          if (latitude && !(v >= -90.0 && v <= 90.0)) {
            return Answer{std::nullopt, "error",
                          "latitude " + formatNumber(v) + " is outside [-90, 90]"};
          }
          return Answer{z ? index.below(u, v, *z) : index.top(u, v), "", ""};
        };
      },
      tree->index);
}

}  // namespace

int sample(const SampleOptions& options, std::istream& in, std::ostream& out, std::ostream& err) {
  try {
    const Surface surface = openSurface(options);

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
      const double x = options.swapXY ? v[1] : v[0], y = options.swapXY ? v[0] : v[1];
      const Answer answer = surface(x, y, count == 3 ? &v[2] : nullptr);
      if (!answer.problem.empty()) {
        fail(answer.token, answer.problem);
        continue;
      }
      const std::optional<Hit>& hit = answer.hit;
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
