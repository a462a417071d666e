// qota sample: heights under points, as a line-oriented filter (see qota_tools.hpp).
#include <gdal.h>
#include <ogr_spatialref.h>

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <exception>
#include <cstring>
#include <filesystem>
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
#include <unistd.h>
#include <vector>

#include "index_source.hpp"
#include "sample_lines.hpp"
#include "qota/crs_transform.hpp"
#include "qota/batch.hpp"
#include "qota/curved.hpp"
#include "qota/dem.hpp"
#include "qota/error.hpp"
#include "qota/geoid.hpp"
#include "qota/mapping_registry.hpp"
#include "qota/kernel_sampler.hpp"
#include "qota/raster_sampler.hpp"
#include "qota/treefile.hpp"
#include "cancel.hpp"
#include "qota_tools.hpp"
#include "text_output.hpp"

namespace qota::tools {
namespace {

using sampling::Answer;
using sampling::inParallel;
using sampling::outside;
using sampling::Query;
using sampling::Surface;

std::unique_ptr<OGRCoordinateTransformation> makeTransform(const std::string& srs, const TreeSource& source) {
  if (srs.empty()) return nullptr;
  if (source.crsWkt.empty()) {
    throw Error(source.path + ": the source has no CRS, so points given in --srs cannot be placed on it");
  }
  return transformTo(*crsFromUser(srs, "--srs"), source.crsWkt,
                     "--srs '" + srs + "': no transformation to the source's CRS");
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
Surface rasterSurface(const std::shared_ptr<RasterSampler>& sampler) {
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

// A raster by one of GDAL's sampling rules (KernelSampler), on one thread (its block cache is
// its own). With a query height, the height when it is at or below it, else none: the rule's
// surface is single-valued.
Surface kernelSurface(const std::shared_ptr<KernelSampler>& sampler) {
  return [sampler](std::span<const Query> q, bool hasZ, std::span<Answer> out) {
    for (std::size_t i = 0; i < q.size(); ++i) {
      out[i] = Answer{};
      const std::optional<double> h = sampler->height(q[i].x, q[i].y);
      if (!h && !sampler->dem().onRaster(q[i].x, q[i].y)) {
        out[i] =
            outside("none", "point (" + formatNumber(q[i].x) + ", " + formatNumber(q[i].y) + ") is off the raster");
      } else if (h && (!hasZ || *h <= q[i].z)) {
        out[i].height = h;
        out[i].world = Eigen::Vector3d(q[i].x, q[i].y, *h);
      }
    }
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
Surface openSurface(const SampleOptions& options, TreeSource& source, bool& integerValues, std::ostream& err) {
  const MappingEntry& entry = mappingEntry(options.mapping);
  if (!isTreeFile(options.source)) requireMappingOptions(options);  // (a tree file's were given when built)
  // The default mapping's rasters go through the streaming sampler: no index at all.
  const bool asMap = entry.map;
  const Resampling rule = resamplingNamed(options.resampling);
  if (rule != Resampling::Triangle && options.fillVoids > 0) {
    throw Error(std::string("-r ") + resamplingName(rule) +
                " reads the raster's own pixels; --fill-voids fills the triangles' surface (-r triangle), or fill "
                "the raster first with gdal_fillnodata");
  }
  if (rule != Resampling::Triangle && (!asMap || isTreeFile(options.source) || !isRaster(options.source))) {
    throw Error(std::string("-r ") + resamplingName(rule) +
                " samples a raster's pixels in the cartesian mapping; a tree file, a mesh or another mapping "
                "answers its triangles (-r triangle)");
  }
  if (asMap && !isTreeFile(options.source)) {
    requireSource(options.source);
    // (with --fill-voids the raster is read whole: the fill reaches across any tile)
    if (isRaster(options.source) && options.fillVoids == 0) {
      // GDAL's block cache (5% of the RAM by default) bounded as well: the sampler's tiles are
      // the cache that matters, and memory must not grow with the raster.
      constexpr GIntBig kGdalCacheBytes = GIntBig{64} << 20;
      if (GDALGetCacheMax64() > kGdalCacheBytes) GDALSetCacheMax64(kGdalCacheBytes);
      if (rule != Resampling::Triangle) {
        auto sampler = std::make_shared<KernelSampler>(options.source, options.band, rule);
        source.path = sampler->dem().path, source.crsWkt = sampler->dem().crsWkt;
        integerValues = sampler->dem().integerValues;
        return kernelSurface(sampler);
      }
      RasterSampler::Options so;
      so.band = options.band;
      auto sampler = std::make_shared<RasterSampler>(options.source, so);
      const DemTerrain& dem = sampler->dem();
      source.path = dem.path, source.crsWkt = dem.crsWkt;
      integerValues = dem.integerValues;
      return rasterSurface(sampler);
    }
  }
  SourceOptions so = options;  // (the source's part of the options)
  so.heightsOnly = true;
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

// Lines of text in: the options of vector layers are refused by name, and so is a vector format
// for the lines out (they would be written as text under its name).
void refuseVectorOptionsForText(const SampleOptions& o) {
  const std::string input = o.inputFile.empty() ? std::string("stdin") : o.inputFile;
  if (!o.outputFormat.empty() || !o.layer.empty() || !o.openOptions.empty() || o.field != "height") {
    throw Error(std::string(!o.outputFormat.empty()  ? "--of"
                            : !o.layer.empty()       ? "--layer"
                            : !o.openOptions.empty() ? "--oo"
                                                     : "--field") +
                " applies to a vector layer of points; " + input + " is read as lines of text");
  }
  if (o.outputFile.empty() || o.outputFile.rfind("/dev/", 0) == 0) return;
  std::string ext = std::filesystem::path(o.outputFile).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  for (const char* vector : {".gpkg", ".geojson", ".json", ".shp", ".fgb", ".kml", ".gml", ".sqlite", ".geojsonl"}) {
    if (ext == vector) {
      throw Error(o.outputFile +
                  ": a vector layer is written for a vector layer of points (-i POINTS.gpkg, .geojson, "
                  ".shp, a CSV with x and y columns); " +
                  input + " is read as lines of text, written as text");
    }
  }
}

}  // namespace

int sample(const SampleOptions& options, std::istream& in, std::ostream& out, std::ostream& err) {
  try {
    if (options.precision > kMaxPrecision) {
      throw Error("-p " + std::to_string(options.precision) + ": at most " + std::to_string(kMaxPrecision) +
                  " decimals");
    }
    TreeSource source;
    bool integerValues = false;
    const Surface surface = openSurface(options, source, integerValues, err);
    const std::unique_ptr<OGRCoordinateTransformation> transform = makeTransform(options.srs, source);

    if (!options.inputFile.empty()) {
      if (const std::unique_ptr<GDALDataset> layer = sampling::openPointLayer(options)) {
        return sampling::sampleLayer(options, *layer, surface, source.crsWkt, integerValues, err) ? 1 : 0;
      }
    }
    refuseVectorOptionsForText(options);
    std::ifstream file;
    std::istream* input = &in;
    std::string where = "stdin";
    if (!options.inputFile.empty()) {
      file.open(options.inputFile, std::ios::binary);
      if (!file) throw Error(options.inputFile + ": cannot read");
      input = &file;
      where = options.inputFile;
    } else if (&in == &std::cin && isatty(STDIN_FILENO) && !options.quiet) {
      // (a person at a terminal who typed `qota sample DEM` and sees nothing happen)
      err << "qota sample: reading points from the terminal, one 'x y' a line; Ctrl-D ends (or give -i FILE)\n";
    }
    // A file is written whole or not at all (atomic_file.hpp); a character device (/dev/null, a
    // terminal) is written in place: there is nothing there to replace or to leave half-written.
    std::optional<AtomicFile> outFile;
    std::ofstream device;
    std::ostream* output = &out;
    if (!options.outputFile.empty()) {
      std::error_code ec;
      if (std::filesystem::is_character_file(std::filesystem::status(options.outputFile, ec))) {
        device.open(options.outputFile, std::ios::out | std::ios::binary);
        if (!device) throw Error(options.outputFile + ": cannot write");
        output = &device;
      } else {
        outFile.emplace(options.outputFile);
        output = &outFile->stream();
      }
    }

    const bool failed =
        sampling::readLines(options, surface, transform.get(), *input, *output, err, where, integerValues);
    if (outFile) {
      outFile->commit();
    } else {
      output->flush();
      if (!*output) throw Error((options.outputFile.empty() ? "the output" : options.outputFile) + ": cannot write");
    }
    return failed ? 1 : 0;
  } catch (...) {
    return reportFailure("sample", err);
  }
}

}  // namespace qota::tools
