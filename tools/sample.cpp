// qota sample: heights under points, as a line-oriented filter (see qota_tools.hpp).
#include <gdal.h>
#include <ogr_spatialref.h>

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <exception>
#include <cstring>
#include <fstream>
#include <future>
#include <functional>
#include <iostream>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <string_view>
#include <thread>
#include <type_traits>
#include <vector>

#include "index_source.hpp"
#include "qota/batch.hpp"
#include "qota/curved.hpp"
#include "qota/dem.hpp"
#include "qota/error.hpp"
#include "qota/geoid.hpp"
#include "qota/mapping_registry.hpp"
#include "qota/raster_sampler.hpp"
#include "qota/treefile.hpp"
#include "cancel.hpp"
#include "qota_tools.hpp"
#include "text_output.hpp"

namespace qota::tools {
namespace {

// "'token' <what>", built by appending (GCC 12 warns falsely on "'" + std::string + "'"), with
// bytes a terminal would not show (control characters, a byte-order mark) written as escapes.
std::string quoted(std::string_view token, std::string_view what) {
  std::string m = "'";
  for (const char c : token) {
    const auto u = static_cast<unsigned char>(c);
    if (u >= 0x20 && u < 0x7f) {
      m += c;
    } else {
      static const char* hex = "0123456789ABCDEF";
      m += c == '\r'   ? std::string("\\r")
           : c == '\t' ? std::string("\\t")
                       : std::string{'\\', 'x', hex[u >> 4], hex[u & 15]};
    }
  }
  m += "' ";
  m += what;
  return m;
}

bool isSeparator(char c) { return c == ' ' || c == '\t' || c == ','; }

// One input line: its coordinates, and the fields after them, passed through to the output.
struct PointLine {
  double v[3] = {0, 0, 0};
  int count = 0;          // coordinates read: 0 for a blank line, else `want`
  std::string_view rest;  // the text after the coordinates and their separators
  char separator = ' ';   // what follows the last coordinate: ',', '\t' or ' '
};

// Reads the first `want` fields of a line as finite numbers (fields are separated by spaces,
// tabs or commas) and keeps the rest of the line as it is. Returns false, with the message in
// `problem`, for a bad line; true for a good (or blank) one, leaving `problem` as it is.
bool parsePointLine(std::string_view line, int want, PointLine& out, std::string& problem) {
  out = PointLine{};
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  std::size_t i = 0;
  while (i < line.size() && isSeparator(line[i])) ++i;
  if (i == line.size()) return true;  // blank
  for (int k = 0; k < want; ++k) {
    while (i < line.size() && isSeparator(line[i])) ++i;
    if (i == line.size()) {
      const char* expected = want == 3 ? "expected 'x y z' (--query-z)" : "expected 'x y'";
      problem = std::string(expected) + ", got " + std::to_string(k) + (k == 1 ? " value" : " values");
      return false;
    }
    // A number ends where its field does (no separator can be part of one).
    double v = 0;
    const auto r = std::from_chars(line.data() + i, line.data() + line.size(), v);
    const std::size_t end = static_cast<std::size_t>(r.ptr - line.data());
    if (r.ec != std::errc() || (end < line.size() && !isSeparator(line[end]))) {
      std::size_t j = i;
      while (j < line.size() && !isSeparator(line[j])) ++j;
      const std::string_view token = line.substr(i, j - i);
      problem = quoted(token, "is not a number");
      return false;
    }
    if (!std::isfinite(v)) {
      problem = quoted(line.substr(i, end - i), "is not a finite number");
      return false;
    }
    out.v[k] = v;
    i = end;
  }
  out.count = want;
  if (i < line.size()) out.separator = line[i] == ',' || line[i] == '\t' ? line[i] : ' ';
  while (i < line.size() && isSeparator(line[i])) ++i;
  out.rest = line.substr(i);
  return true;
}

std::unique_ptr<OGRCoordinateTransformation> makeTransform(const std::string& srs, const TreeSource& source) {
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
Answer outside(const char* token, std::string problem) { return {std::nullopt, {}, token, std::move(problem)}; }

// A point of a line: (x, y) in the input's order after -w and --srs, z the query height.
struct Query {
  double x = 0, y = 0, z = 0;
};

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

// A surface answered point by point (a const index: any number of threads at once).
template <class One>
Surface pointByPoint(One one) {
  return [one = std::move(one)](std::span<const Query> q, bool hasZ, std::span<Answer> out) {
    inParallel(q.size(), 4096, [&](std::size_t lo, std::size_t hi) {
      for (std::size_t i = lo; i < hi; ++i) out[i] = one(q[i].x, q[i].y, hasZ ? &q[i].z : nullptr);
    });
  };
}

// The raster grid a tree was built from (its footprint, for the outer half-pixel rule), or
// nothing for a mesh source.
std::shared_ptr<const DemTerrain> gridOf(const TreeSource& source) {
  if (source.width <= 0 || source.height <= 0) return nullptr;
  auto grid = std::make_shared<DemTerrain>();
  grid->path = source.path;
  grid->width = source.width, grid->height = source.height;
  grid->geotransform = source.geotransform;
  grid->lonLat = crsIsGeographic(source.crsWkt) && source.geotransform[2] == 0 && source.geotransform[4] == 0;
  return grid;
}

// The outer half-pixel rule on a raster's footprint (dem.hpp): (x, y) moved onto the nearest
// point of the outermost pixel centres' lines; false (with the problem) off the raster.
bool onSurface(const DemTerrain* grid, double& x, double& y, std::string& problem,
               const std::array<double, 6>* inverse = nullptr) {
  if (!grid) return true;
  const auto p = inverse ? grid->surfacePoint(x, y, *inverse) : grid->surfacePoint(x, y);
  if (!p) {
    problem = "point (" + formatNumber(x) + ", " + formatNumber(y) + ") is off the raster";
    return false;
  }
  x = (*p)[0], y = (*p)[1];
  return true;
}

// A raster in the Cartesian mapping, read tile by tile (RasterSampler): memory bounded by the
// tile cache, never the whole raster; the same answers as its whole terrain.
Surface rasterSurface(std::shared_ptr<RasterSampler> sampler) {
  return [sampler](std::span<const Query> q, bool hasZ, std::span<Answer> out) {
    const DemTerrain& dem = sampler->dem();
    const std::array<double, 6> inverse = dem.inverseGeotransform();
    std::vector<double> xs(q.size()), ys(q.size()), zs(hasZ ? q.size() : 0);
    std::vector<std::optional<double>> heights(q.size());
    inParallel(q.size(), 8192, [&](std::size_t lo, std::size_t hi) {
      for (std::size_t i = lo; i < hi; ++i) {
        xs[i] = q[i].x, ys[i] = q[i].y;
        if (hasZ) zs[i] = q[i].z;
        out[i] = Answer{};
        if (!onSurface(&dem, xs[i], ys[i], out[i].problem, &inverse)) {
          out[i].token = "none";
          xs[i] = ys[i] = std::numeric_limits<double>::quiet_NaN();  // off: no terrain
        }
      }
    });
    sampler->heights(xs, ys, zs, heights);
    inParallel(q.size(), 8192, [&](std::size_t lo, std::size_t hi) {
      for (std::size_t i = lo; i < hi; ++i) {
        if (!out[i].problem.empty() || !heights[i]) continue;
        out[i].height = heights[i];
        out[i].world = Eigen::Vector3d(q[i].x, q[i].y, *heights[i]);
      }
    });
  };
}

template <class... F>
struct Overloaded : F... {
  using F::operator()...;
};
template <class... F>
Overloaded(F...) -> Overloaded<F...>;  // (clang 14 deduces no aggregate's arguments without it)

// A terrain indexed in the Cartesian mapping as a map (a mesh, a tree file): answers in the
// source's own x, y and up; nullopt for an index in another mapping.
std::optional<Surface> mapAnswers(const std::shared_ptr<TreeFile>& tree,
                                  const std::shared_ptr<const DemTerrain>& grid) {
  return std::visit(
      Overloaded{[&](const CartesianIndex& indexRef) -> std::optional<Surface> {
                   const CartesianIndex* index = &indexRef;
                   const CartesianMapping& mapping = index->mapping();
                   return pointByPoint([tree, index, mapping, grid](double x, double y, const double* z) {
                     const double px = x, py = y;
                     std::string problem;
                     if (!onSurface(grid.get(), x, y, problem)) return outside("none", problem);
                     const Eigen::Vector3d m = mapping.toMapped(Eigen::Vector3d(x, y, z ? *z : 0.0));
                     if (!grid && !index->tree().box().contains(m.x(), m.y())) {  // a mesh: off its footprint
                       return outside("none",
                                      "point (" + formatNumber(px) + ", " + formatNumber(py) + ") is off the terrain");
                     }
                     const std::optional<Hit> hit = z ? index->below(m.x(), m.y(), m.z()) : index->top(m.x(), m.y());
                     if (!hit) return Answer{};
                     // The height in the source's own coordinates: along "up" from its world origin (a mesh's
                     // index works around the centre of its box, a raster's around its centre at z = 0).
                     const double height = mapping.vertical() ? hit->world.z() : -hit->world.dot(mapping.gravity());
                     return Answer{height, Eigen::Vector3d(px, py, height), "", ""};
                   });
                 },
                 [](const auto&) -> std::optional<Surface> { return std::nullopt; }},
      tree->index);
}

// The terrain of options.source: a raster in the Cartesian mapping through the tile sampler,
// else an index (a tree file, a mesh, or a raster in a curved mapping) queried point by point.
Surface openSurface(const SampleOptions& options, TreeSource& source, std::ostream& err) {
  const MappingEntry& entry = mappingEntry(options.mapping);
  if (!isTreeFile(options.source)) {  // (a tree file's options were given when it was built)
    requireMappingTakes(entry, options.radius != 0, &MappingEntry::radius, "--radius");
    requireMappingTakes(entry, options.length != 0, &MappingEntry::length, "--length");
    requireMappingTakes(entry, options.origin.has_value(), &MappingEntry::origin, "--origin");
    requireMappingTakes(entry, !options.heightRef.empty(), &MappingEntry::ellipsoid, "--height-ref");
  }
  // The default mapping's rasters go through the streaming sampler: no index at all.
  const bool asMap = entry.map;
  if (asMap && !isTreeFile(options.source)) {
    requireSource(options.source);
    if (isRaster(options.source)) {
      // GDAL's block cache (5% of the RAM by default) bounded as well: the sampler's tiles are
      // the cache that matters, and memory must not grow with the raster.
      constexpr GIntBig kGdalCacheBytes = GIntBig{64} << 20;
      if (GDALGetCacheMax64() > kGdalCacheBytes) GDALSetCacheMax64(kGdalCacheBytes);
      RasterSampler::Options so;
      so.band = options.band;
      auto sampler = std::make_shared<RasterSampler>(options.source, so);
      const DemTerrain& dem = sampler->dem();
      source.path = dem.path, source.crsWkt = dem.crsWkt;
      return rasterSurface(std::move(sampler));
    }
  }
  SourceOptions so;
  so.source = options.source;
  so.mapping = options.mapping;
  so.radius = options.radius;
  so.length = options.length;
  so.band = options.band;
  so.heightsOnly = true;
  so.terrain = options.terrain;
  so.heightRef = options.heightRef;
  so.origin = options.origin;
  if (!options.outputHeightRef.empty() && options.outputHeightRef != "ellipsoid") {
    throw Error("--output-height-ref '" + options.outputHeightRef +
                "': heights are printed over the source's own "
                "reference, or over the ellipsoid with --output-height-ref ellipsoid");
  }
  if (!isTreeFile(options.source)) {
    // (answers in an east-north-up frame are its metres: no reference to print them over)
    requireMappingTakes(entry, !options.outputHeightRef.empty(), &MappingEntry::ellipsoidHeights,
                        "--output-height-ref");
  }
  auto tree = std::make_shared<TreeFile>(openIndex(so));
  if (tree->source.path.empty()) tree->source.path = options.source;
  source = tree->source;
  const std::shared_ptr<const DemTerrain> grid = gridOf(tree->source);

  // The map's own index (a mesh, or a tree file of a raster) answers in map coordinates; every
  // other mapping goes through the index's (u, v, h), its registry entry saying what they are.
  if (auto answer = mapAnswers(tree, grid)) return *answer;
  if (!options.srs.empty()) {
    throw Error("--srs applies to the cartesian mapping only; the " + std::string(mappingNameOf(tree->index)) +
                " mapping reads its own coordinates ('" + mappingEntry(mappingNameOf(tree->index)).line + "')");
  }
  const MappingEntry& built = mappingEntry(mappingNameOf(tree->index));
  // A geodetic source's heights are in the raster's vertical unit (converted to metres for the
  // ellipsoid) and over its own reference (a geoid's undulation added to place them over the
  // ellipsoid): the query height comes in them and the answer goes out in them, as for
  // cartesian, unless the answer is asked over the ellipsoid.
  const double metres = tree->source.metresPerUnit;
  auto geoid = std::make_shared<Geoid>(storedHeightReference(tree->source.heightRef, tree->source.geoidGrid));
  const bool overEllipsoid = options.outputHeightRef == "ellipsoid";
  if (!options.quiet && !geoid->ellipsoidal() && tree->source.heightRef.find("assumed") != std::string::npos) {
    err << "qota sample: note: " << tree->source.path << ": heights taken over the " << tree->source.heightRef << " ("
        << kHeightRefChoices << ")\n";
  }
  return std::visit(
      [&](const auto& index) -> Surface {
        // (u a longitude and v a latitude; heights over an ellipsoid, in the raster's unit)
        const bool kLatitude = built.lonLat, kGeodetic = built.lonLat && built.ellipsoid;
        const bool kSpherical = built.lonLat && !built.ellipsoid;
        return pointByPoint([tree, &index, grid, metres, geoid, overEllipsoid, kLatitude, kGeodetic, kSpherical](
                                double u, double v, const double* z) {
          if (kLatitude && !(v >= -90.0 && v <= 90.0)) {
            return outside("error", "latitude " + formatNumber(v) + " is outside [-90, 90]");
          }
          std::string problem;
          if (kGeodetic && !onSurface(grid.get(), u, v, problem)) return outside("none", problem);
          // A regional raster as a planet: off its footprint is off the terrain (its inside keeps
          // the mesh's own closure: no outer half pixel is moved onto the centres here).
          if (kSpherical && grid && !grid->onRaster(u, v)) {
            return outside("none", "point (" + formatNumber(u) + ", " + formatNumber(v) + ") is off the raster");
          }
          if (kLatitude) u -= 360.0 * std::floor((u + 180.0) / 360.0);  // the index's longitudes: [-180, 180)
          if (!grid && !index.tree().box().contains(u, v)) {            // a mesh: off its footprint
            return outside("none", "point (" + formatNumber(u) + ", " + formatNumber(v) + ") is off the terrain");
          }
          const double scale = kGeodetic ? metres : 1.0;
          const double n = kGeodetic ? geoid->undulation(u, v) : 0.0;  // (0 over the ellipsoid)
          if (std::isnan(n))
            return outside("none",
                           "point (" + formatNumber(u) + ", " + formatNumber(v) + ") is outside the geoid grid");
          // (over a geoid, a height printed and asked again is widened by a few units in the last
          // place, so that it finds its own surface: z + N - N is not always z to the last bit)
          const double zh = z ? *z * scale + n : 0.0;
          const double below = n != 0 ? zh + std::fabs(zh) * 8 * std::numeric_limits<double>::epsilon() : zh;
          const std::optional<Hit> hit = z ? index.below(u, v, below) : index.top(u, v);
          if (!hit) return Answer{};
          return Answer{(hit->height - (overEllipsoid ? 0.0 : n)) / scale, hit->world, "", ""};
        });
      },
      tree->index);
}

// Appends a number as formatNumber writes it, without a string per number.
void appendNumber(std::string& out, double value, int precision) {
  char buf[340 + kMaxPrecision];
  precision = std::min(precision, kMaxPrecision);
  const auto r = precision < 0 ? std::to_chars(buf, buf + sizeof buf, value)
                               : std::to_chars(buf, buf + sizeof buf, value, std::chars_format::fixed, precision);
  if (r.ec != std::errc()) throw Error("cannot format a number");
  out.append(buf, r.ptr);
}

// A line's outcome: its output text is written in order; a failure's message goes to stderr.
struct LineResult {
  std::string_view line;
  PointLine p;
  std::string problem;      // parse error, or the surface's
  std::string token;        // printed in place of the height when there is a problem
  std::uint32_t query = 0;  // its query's index when p.count > 0
};

// The cores a batch's lines are parsed and formatted on.
const std::size_t kThreads = std::max(1u, std::thread::hardware_concurrency());

// The line loop: input read in large blocks and cut into lines; each batch of lines parsed on
// both cores, transformed (--srs) and answered as one batch, formatted on both cores, written
// in order. The text of every line is as the line-by-line loop wrote it.
class LineLoop {
 public:
  LineLoop(const SampleOptions& options, const Surface& surface, OGRCoordinateTransformation* transform,
           std::ostream& output, std::ostream& err, std::string where)
      : o_(options), surface_(surface), transform_(transform), out_(output), err_(err), where_(std::move(where)) {}

  // Reads `in` to its end. Returns whether any line failed.
  bool run(std::istream& in) {
    // The next block is read while this one's lines are answered: on another thread, so the
    // input must not flush the output it is tied to (std::cin to std::cout) meanwhile.
    std::ostream* const tied = in.tie(nullptr);
    struct Retie {
      std::istream& in;
      std::ostream* tied;
      ~Retie() { in.tie(tied); }
    } retie{in, tied};
    constexpr std::size_t kBlock = 1 << 22;
    const auto readBlock = [&in, this](std::string& raw) {  // true at the end of the input
      raw.resize(kBlock);
      in.read(raw.data(), static_cast<std::streamsize>(kBlock));
      raw.resize(static_cast<std::size_t>(in.gcount()));
      if (in.bad()) throw Error(where_ + ": read error");
      return !in;
    };
    std::string data, raw, ahead;  // data: the last block's unfinished line, then this block
    std::vector<std::string_view> lines;
    bool first = true, crOnly = false;
    for (bool end = readBlock(raw);;) {
      if (first) {
        // A UTF-8 byte-order mark is not part of the first line; a file whose lines end in a
        // carriage return alone (classic Mac OS) has no newline in its first block.
        if (raw.compare(0, 3, "\xEF\xBB\xBF") == 0) raw.erase(0, 3);
        crOnly = raw.find('\n') == std::string::npos && raw.find('\r') != std::string::npos;
        first = false;
      }
      if (crOnly) std::replace(raw.begin(), raw.end(), '\r', '\n');
      data.append(raw);
      std::future<bool> next;
      if (!end) next = std::async(std::launch::async, [&] { return readBlock(ahead); });
      const std::size_t start = splitLines(data, end, lines);
      constexpr std::size_t kBatch = 1 << 16;
      for (std::size_t b = 0; b < lines.size(); b += kBatch) {
        throwIfCancelled();
        batchOf(std::span<const std::string_view>(lines).subspan(b, std::min(kBatch, lines.size() - b)));
      }
      data.erase(0, start);
      if (end) break;
      end = next.get();
      raw.swap(ahead);
    }
    if (failures_ > kMostMessages) {
      err_ << "qota sample: " << where_ << ": " << failures_ - kMostMessages << " more failed lines (" << failures_
           << " in all; the first " << kMostMessages << " are named above)\n";
    }
    return failed_;
  }

 private:
  // Repeated per-line messages are capped (as GDAL caps its repeated errors): the first ones,
  // then a count.
  static constexpr std::uint64_t kMostMessages = 20;
  std::uint64_t failures_ = 0;
  // The complete lines of data (and its unfinished last one at the end of the input), found on
  // every core; returns where the unfinished line starts.
  static std::size_t splitLines(const std::string& data, bool end, std::vector<std::string_view>& lines) {
    const std::size_t slices = data.size() >= (1u << 20) ? kThreads : 1;
    std::vector<std::vector<std::size_t>> ends(slices);  // each slice's newlines
    const std::size_t each = (data.size() + slices - 1) / slices;
    inParallel(slices, 1, [&](std::size_t lo, std::size_t hi) {
      for (std::size_t s = lo; s < hi; ++s) {
        std::vector<std::size_t> found;  // (moved in at the end, as the format's text)
        const char* p = data.data() + std::min(data.size(), s * each);
        const char* stop = data.data() + std::min(data.size(), (s + 1) * each);
        while (const void* nl = std::memchr(p, '\n', static_cast<std::size_t>(stop - p))) {
          p = static_cast<const char*>(nl);
          found.push_back(static_cast<std::size_t>(p - data.data()));
          ++p;
        }
        ends[s] = std::move(found);
      }
    });
    lines.clear();
    std::size_t start = 0;
    for (const auto& e : ends) {
      for (const std::size_t nl : e) lines.emplace_back(data.data() + start, nl - start), start = nl + 1;
    }
    if (end && start < data.size()) {  // a last line without its newline
      lines.emplace_back(data.data() + start, data.size() - start);
      start = data.size();
    }
    return start;
  }

  void batchOf(std::span<const std::string_view> lines) {
    const std::size_t n = lines.size();
    const int want = o_.queryZ ? 3 : 2;
    results_.resize(n);
    const std::uint64_t first = lineNo_ + 1;
    lineNo_ += n;
    // Parse, and number the queries: both on every core, in the same slices (a slice's queries
    // follow the earlier slices').
    const std::size_t slices = std::max<std::size_t>(1, std::min<std::size_t>(kThreads, n / 2048));
    const std::size_t each = (n + slices - 1) / slices;
    std::vector<std::size_t> count(slices + 1, 0);
    inParallel(slices, 1, [&](std::size_t lo, std::size_t hi) {
      for (std::size_t s = lo; s < hi; ++s) {
        std::size_t queries = 0;  // (counted here: slices counting in `count` share its cache line)
        for (std::size_t i = s * each; i < std::min(n, (s + 1) * each); ++i) {
          LineResult& r = results_[i];  // reset field by field: the strings keep their buffers
          r.line = lines[i];
          r.p = PointLine{};
          r.problem.clear(), r.token.clear();
          r.query = 0;
          if (o_.header && first + i == 1) continue;  // (written as the header)
          if (!parsePointLine(lines[i], want, r.p, r.problem)) {
            r.token = "error";
            if (first + i == 1 && !o_.header) r.problem += " (a header line? --header skips it)";
          }
          queries += r.problem.empty() && r.p.count > 0;
        }
        count[s + 1] = queries;
      }
    });
    for (std::size_t s = 0; s < slices; ++s) count[s + 1] += count[s];
    // Queries, placed (--srs), answered.
    queries_.resize(count[slices]);
    answers_.resize(count[slices]);
    inParallel(slices, 1, [&](std::size_t lo, std::size_t hi) {
      for (std::size_t s = lo; s < hi; ++s) {
        std::size_t k = count[s];
        for (std::size_t i = s * each; i < std::min(n, (s + 1) * each); ++i) {
          LineResult& r = results_[i];
          if (!r.problem.empty() || r.p.count == 0) continue;
          r.query = static_cast<std::uint32_t>(k);
          Query& q = queries_[k];
          q.x = o_.swapXY ? r.p.v[1] : r.p.v[0], q.y = o_.swapXY ? r.p.v[0] : r.p.v[1], q.z = r.p.v[2];
          ++k;  // (its answer is set whole by the surface, or by the --srs failure below)
        }
      }
    });
    std::vector<std::uint8_t> placed(queries_.size(), 1);
    if (transform_ && !queries_.empty()) {
      std::vector<double> xs(queries_.size()), ys(queries_.size());
      std::vector<int> ok(queries_.size(), 0);
      for (std::size_t k = 0; k < queries_.size(); ++k) xs[k] = queries_[k].x, ys[k] = queries_[k].y;
      transform_->Transform(static_cast<int>(queries_.size()), xs.data(), ys.data(), nullptr, ok.data());
      for (std::size_t k = 0; k < queries_.size(); ++k) {
        if (ok[k] && std::isfinite(xs[k]) && std::isfinite(ys[k])) {
          queries_[k].x = xs[k], queries_[k].y = ys[k];
        } else {
          placed[k] = 0;
          answers_[k] = outside("error", "cannot transform (" + formatNumber(queries_[k].x) + ", " +
                                             formatNumber(queries_[k].y) + ") from " + o_.srs + " to the source's CRS");
        }
      }
    }
    answer(placed);
    // Format, on every core.
    std::vector<std::string> text(slices);
    inParallel(slices, 1, [&](std::size_t lo, std::size_t hi) {
      for (std::size_t s = lo; s < hi; ++s) {
        std::string t;  // (moved in at the end: the slices' strings share a cache line)
        t.reserve(each * 24);
        for (std::size_t i = s * each; i < std::min(n, (s + 1) * each); ++i) format(i, first + i, t);
        text[s] = std::move(t);
      }
    });
    for (std::size_t s = 0; s < slices; ++s) out_.write(text[s].data(), static_cast<std::streamsize>(text[s].size()));
    for (std::size_t i = 0; i < n; ++i) {
      if (results_[i].problem.empty()) continue;
      failed_ = true;
      if (++failures_ > kMostMessages) continue;  // (counted, and said once at the end)
      err_ << "qota sample: " << where_ << ':' << first + i << ": " << results_[i].problem << '\n';
    }
  }

  // The surface's answers for the placed queries, in one batch.
  void answer(const std::vector<std::uint8_t>& placed) {
    if (std::find(placed.begin(), placed.end(), 0) == placed.end()) {  // every one (no --srs failure)
      surface_(queries_, o_.queryZ, answers_);
      return;
    }
    std::vector<Query> q;
    std::vector<std::uint32_t> at;
    for (std::size_t k = 0; k < queries_.size(); ++k) {
      if (placed[k]) q.push_back(queries_[k]), at.push_back(static_cast<std::uint32_t>(k));
    }
    std::vector<Answer> a(q.size());
    surface_(q, o_.queryZ, a);
    for (std::size_t j = 0; j < q.size(); ++j) answers_[at[j]] = std::move(a[j]);
  }

  void format(std::size_t i, std::uint64_t lineNo, std::string& t) {
    LineResult& r = results_[i];
    if (o_.header && lineNo == 1) {
      header(r.line, t);
      return;
    }
    if (r.problem.empty() && r.p.count > 0) {
      const Answer& a = answers_[r.query];
      if (!a.problem.empty()) {
        r.problem = a.problem, r.token = a.token;
      } else if (!a.height) {
        t += "none";
      } else {
        appendNumber(t, *a.height, o_.precision);
        if (o_.printWorld) {
          for (int k = 0; k < 3; ++k) t += r.p.separator, appendNumber(t, a.world[k], o_.precision);
        }
      }
    }
    if (!r.problem.empty()) t += r.token;
    if (r.problem.empty() || r.p.count > 0) passThrough(t, r.p);
    t += '\n';
  }

  // The header's coordinate names become the answer's; its other names pass through.
  void header(std::string_view line, std::string& t) const {
    const int want = o_.queryZ ? 3 : 2;
    PointLine p;
    std::size_t i = 0;
    for (int k = 0; k < want; ++k) {
      while (i < line.size() && isSeparator(line[i])) ++i;
      while (i < line.size() && !isSeparator(line[i])) ++i;
    }
    if (i < line.size()) p.separator = line[i] == ',' || line[i] == '\t' ? line[i] : ' ';
    while (i < line.size() && isSeparator(line[i])) ++i;
    std::string_view rest = line.substr(i);
    if (!rest.empty() && rest.back() == '\r') rest.remove_suffix(1);
    p.rest = rest;
    const char s = p.separator;
    t += "height";
    if (o_.printWorld) (((t += s) += 'x') += s) += 'y', (t += s) += 'z';
    passThrough(t, p);
    t += '\n';
  }

  static void passThrough(std::string& t, const PointLine& p) {
    if (!p.rest.empty()) t += p.separator, t += p.rest;
  }

  const SampleOptions& o_;
  const Surface& surface_;
  OGRCoordinateTransformation* transform_;
  std::ostream& out_;
  std::ostream& err_;
  std::string where_;
  std::uint64_t lineNo_ = 0;
  bool failed_ = false;
  std::vector<LineResult> results_;
  std::vector<Query> queries_;
  std::vector<Answer> answers_;
};

}  // namespace

int sample(const SampleOptions& options, std::istream& in, std::ostream& out, std::ostream& err) {
  try {
    if (options.precision > kMaxPrecision) {
      throw Error("-p " + std::to_string(options.precision) + ": at most " + std::to_string(kMaxPrecision) +
                  " decimals");
    }
    TreeSource source;
    const Surface surface = openSurface(options, source, err);
    const std::unique_ptr<OGRCoordinateTransformation> transform = makeTransform(options.srs, source);

    std::ifstream file;
    std::istream* input = &in;
    std::string where = "stdin";
    if (!options.inputFile.empty()) {
      file.open(options.inputFile, std::ios::binary);
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

    LineLoop loop(options, surface, transform.get(), *output, err, where);
    const bool failed = loop.run(*input);
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
