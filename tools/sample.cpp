// qota sample: heights under points, as a line-oriented filter (see qota_tools.hpp).
#include <ogr_spatialref.h>

#include <charconv>
#include <fstream>
#include <functional>
#include <iostream>
#include <memory>
#include <optional>
#include <string_view>
#include <type_traits>
#include <vector>

#include "index_source.hpp"
#include "qota/curved.hpp"
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

bool isSeparator(char c) { return c == ' ' || c == '\t' || c == ','; }

// One input line: its coordinates, and the fields after them, passed through to the output.
struct PointLine {
  double v[3] = {0, 0, 0};
  int count = 0;               // coordinates read: 0 for a blank line, else `want`
  std::string_view rest;       // the text after the coordinates and their separators
  char separator = ' ';        // what follows the last coordinate: ',', '\t' or ' '
};

// Reads the first `want` fields of a line as finite numbers (fields are separated by spaces,
// tabs or commas) and keeps the rest of the line as it is. Returns an error message, or "" when
// the line is good (or blank).
std::string parsePointLine(std::string_view line, int want, PointLine& out) {
  out = PointLine{};
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  std::size_t i = 0;
  while (i < line.size() && isSeparator(line[i])) ++i;
  if (i == line.size()) return "";  // blank
  const char* expected = want == 3 ? "expected 'x y z' (--query-z)" : "expected 'x y'";
  for (int k = 0; k < want; ++k) {
    while (i < line.size() && isSeparator(line[i])) ++i;
    if (i == line.size()) {
      return std::string(expected) + ", got " + std::to_string(k) + (k == 1 ? " value" : " values");
    }
    std::size_t j = i;
    while (j < line.size() && !isSeparator(line[j])) ++j;
    const std::string_view token = line.substr(i, j - i);
    double v = 0;
    const auto r = std::from_chars(token.data(), token.data() + token.size(), v);
    if (r.ec != std::errc() || r.ptr != token.data() + token.size()) {
      return quoted(token, "is not a number");
    }
    if (!std::isfinite(v)) return quoted(token, "is not a finite number");
    out.v[k] = v;
    i = j;
  }
  out.count = want;
  if (i < line.size()) out.separator = line[i] == ',' || line[i] == '\t' ? line[i] : ' ';
  while (i < line.size() && isSeparator(line[i])) ++i;
  out.rest = line.substr(i);
  return "";
}

std::unique_ptr<OGRCoordinateTransformation> makeTransform(const std::string& srs,
                                                           const TreeSource& source) {
  if (srs.empty()) return nullptr;
  if (source.crsWkt.empty()) {
    throw Error(source.path + ": the source has no CRS, so points given in --srs cannot be placed on it");
  }
  OGRSpatialReference from, to;
  if (from.SetFromUserInput(srs.c_str()) != OGRERR_NONE) {
    throw Error("--srs '" + srs + "' is not a coordinate reference system GDAL knows");
  }
  to.importFromWkt(source.crsWkt.c_str());
  from.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  to.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  std::unique_ptr<OGRCoordinateTransformation> ct(OGRCreateCoordinateTransformation(&from, &to));
  if (!ct) throw Error("--srs '" + srs + "': no transformation to the source's CRS");
  return ct;
}

// One answer of a surface: the height and world point, or nothing; `problem` set when the point
// is outside the surface's domain (printed as `token`, with the message on stderr).
struct Answer {
  std::optional<double> height;
  Eigen::Vector3d world = Eigen::Vector3d::Zero();
  std::string token, problem;
};
// (x, y) in the input's order after -w; z: the query height, or null for the top surface.
using Surface = std::function<Answer(double x, double y, const double* z)>;

Answer outside(const char* token, std::string problem) { return {std::nullopt, {}, token, std::move(problem)}; }

// The raster grid a tree was built from (its footprint, for the outer half-pixel rule), or
// nothing for a mesh source.
std::shared_ptr<const DemTerrain> gridOf(const TreeSource& source) {
  if (source.width <= 0 || source.height <= 0) return nullptr;
  auto grid = std::make_shared<DemTerrain>();
  grid->path = source.path;
  grid->width = source.width, grid->height = source.height;
  grid->geotransform = source.geotransform;
  return grid;
}

// The terrain of options.source (a tree file, or a raster or mesh in options.mapping), with its
// query. The index lives in the returned closure.
Surface openSurface(const SampleOptions& options) {
  SourceOptions so;
  so.source = options.source;
  so.mapping = options.mapping;
  so.radius = options.radius;
  so.length = options.length;
  so.band = options.band;
  so.heightsOnly = true;
  so.terrain = options.terrain;
  auto tree = std::make_shared<TreeFile>(openIndex(so));
  if (tree->source.path.empty()) tree->source.path = options.source;
  const std::shared_ptr<const DemTerrain> grid = gridOf(tree->source);
  // Points off the raster, and the outer half pixel: the height of the nearest point on the
  // outermost pixel centres' lines (dem.hpp). xy is moved there; false when off the raster.
  const auto onSurface = [grid](double& x, double& y, std::string& problem) {
    if (!grid) return true;
    const auto p = grid->surfacePoint(x, y);
    if (!p) {
      problem = "point (" + formatNumber(x) + ", " + formatNumber(y) + ") is off the raster";
      return false;
    }
    x = (*p)[0], y = (*p)[1];
    return true;
  };

  if (const TerrainIndex* index = std::get_if<TerrainIndex>(&tree->index)) {
    std::shared_ptr<OGRCoordinateTransformation> transform = makeTransform(options.srs, tree->source);
    const CartesianMapping& mapping = index->mapping();
    return [tree, index, mapping, transform, onSurface, srs = options.srs](double x0, double y0,
                                                                           const double* z) {
      double x = x0, y = y0;
      if (transform && !transform->Transform(1, &x, &y)) {
        return outside("error", "cannot transform (" + formatNumber(x0) + ", " + formatNumber(y0) +
                                    ") from " + srs + " to the source's CRS");
      }
      const double px = x, py = y;
      std::string problem;
      if (!onSurface(x, y, problem)) return outside("none", problem);
      const Eigen::Vector3d m = mapping.toMapped(Eigen::Vector3d(x, y, z ? *z : 0.0));
      const std::optional<Hit> hit = z ? index->below(m.x(), m.y(), m.z()) : index->top(m.x(), m.y());
      if (!hit) return Answer{};
      // The height in the source's own coordinates: along "up" from its world origin (a mesh's
      // index works around the centre of its box, a raster's around its centre at z = 0).
      const double height = mapping.vertical() ? hit->world.z() : -hit->world.dot(mapping.gravity());
      return Answer{height, Eigen::Vector3d(px, py, height), "", ""};
    };
  }
  if (!options.srs.empty()) {
    throw Error("--srs applies to the cartesian mapping only; the " +
                std::string(mappingNameOf(tree->index)) +
                " mapping reads longitude/latitude (or angle/axial) coordinates");
  }
  // A geodetic source's heights are in the raster's vertical unit (converted to metres for the
  // ellipsoid): the query height comes in it and the answer goes out in it, as for cartesian.
  const double metres = tree->source.metresPerUnit;
  return std::visit(
      [&](const auto& index) -> Surface {
        using Index = std::decay_t<decltype(index)>;
        constexpr bool kGeodetic = std::is_same_v<Index, GeodeticIndex>;
        constexpr bool kLatitude = !std::is_same_v<Index, CylindricalIndex>;
        return [tree, &index, onSurface, metres](double u, double v, const double* z) {
          if (kLatitude && !(v >= -90.0 && v <= 90.0)) {
            return outside("error", "latitude " + formatNumber(v) + " is outside [-90, 90]");
          }
          std::string problem;
          if (kGeodetic && !onSurface(u, v, problem)) return outside("none", problem);
          const double scale = kGeodetic ? metres : 1.0;
          const std::optional<Hit> hit = z ? index.below(u, v, *z * scale) : index.top(u, v);
          if (!hit) return Answer{};
          return Answer{hit->height / scale, hit->world, "", ""};
        };
      },
      tree->index);
}

// What a line's answer is followed by: the fields after its coordinates, if any.
void passThrough(std::ostream& out, const PointLine& p) {
  if (!p.rest.empty()) out << p.separator << p.rest;
}

}  // namespace

int sample(const SampleOptions& options, std::istream& in, std::ostream& out, std::ostream& err) {
  try {
    if (options.precision > kMaxPrecision) {
      throw Error("-p " + std::to_string(options.precision) + ": at most " +
                  std::to_string(kMaxPrecision) + " decimals");
    }
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

    const int want = options.queryZ ? 3 : 2;
    bool failed = false;
    std::string line;
    for (std::uint64_t lineNo = 1; std::getline(*input, line); ++lineNo) {
      const auto fail = [&](const std::string& token, const std::string& message) {
        *output << token;
        err << "qota sample: " << where << ':' << lineNo << ": " << message << '\n';
        failed = true;
      };
      PointLine p;
      if (options.header && lineNo == 1) {
        // The header's coordinate names become the answer's; its other names pass through.
        std::size_t i = 0;
        for (int k = 0; k < want; ++k) {
          while (i < line.size() && isSeparator(line[i])) ++i;
          while (i < line.size() && !isSeparator(line[i])) ++i;
        }
        if (i < line.size()) p.separator = line[i] == ',' || line[i] == '\t' ? line[i] : ' ';
        while (i < line.size() && isSeparator(line[i])) ++i;
        std::string_view rest(line);
        rest = rest.substr(i);
        if (!rest.empty() && rest.back() == '\r') rest.remove_suffix(1);
        p.rest = rest;
        const char s = p.separator;
        *output << "height";
        if (options.printWorld) *output << s << 'x' << s << 'y' << s << 'z';
        passThrough(*output, p);
        *output << '\n';
        continue;
      }
      if (const std::string problem = parsePointLine(line, want, p); !problem.empty()) {
        fail("error", problem + (lineNo == 1 && !options.header ? " (a header line? --header skips it)" : ""));
        *output << '\n';
        continue;
      }
      if (p.count == 0) {
        *output << '\n';
        continue;
      }
      const double x = options.swapXY ? p.v[1] : p.v[0], y = options.swapXY ? p.v[0] : p.v[1];
      const Answer answer = surface(x, y, options.queryZ ? &p.v[2] : nullptr);
      if (!answer.problem.empty()) {
        fail(answer.token, answer.problem);
      } else if (!answer.height) {
        *output << "none";
      } else {
        *output << formatNumber(*answer.height, options.precision);
        if (options.printWorld) {
          for (int k = 0; k < 3; ++k) *output << p.separator << formatNumber(answer.world[k], options.precision);
        }
      }
      passThrough(*output, p);
      *output << '\n';
    }
    if (input->bad()) throw Error(where + ": read error");
    if (outFile) {
      outFile->commit();
    } else {
      output->flush();
      if (!*output) throw Error("cannot write the output");
    }
    return failed ? 1 : 0;
  } catch (...) {
    return reportFailure("sample", err);
  }
}

}  // namespace qota::tools
