// qota viewshed: what an observer sees of a DEM (see qota_tools.hpp and qota/viewshed.hpp).
#include "qota/crs_transform.hpp"
#include "qota/viewshed.hpp"

#include <Eigen/Geometry>
#include <gdal_priv.h>
#include <ogr_spatialref.h>
#include <ogrsf_frmts.h>
#include <strings.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <ostream>

#include "qota/error.hpp"
#include "qota/memory_budget.hpp"
#include "preview.hpp"
#include "qota_tools.hpp"
#include "raster_output.hpp"
#include "shadow_parts.hpp"
#include "text_output.hpp"

namespace qota::tools {
namespace {

// The hillshade's light in previews: from the north-west, 45 degrees up (gdaldem's default).
const Eigen::Vector3d kPreviewLight = Eigen::Vector3d(-0.5, 0.5, std::sqrt(0.5)).normalized();

// Points from `from` (a CRS GDAL reads; empty: the raster's own) into the raster's CRS, in place.
// `what` names them in errors.
void toRasterCrs(const OGRSpatialReference* from, const DemTerrain& dem, std::vector<Observer>& points,
                 const std::string& what) {
  if (!from || points.empty()) return;
  if (dem.crsWkt.empty()) throw Error(dem.path + ": the raster has no CRS, so " + what + " cannot be placed on it");
  const std::unique_ptr<OGRCoordinateTransformation> ct =
      transformTo(*from, dem.crsWkt, what + ": no transformation to the raster's CRS");
  for (Observer& p : points) {
    const double x0 = p.x, y0 = p.y;
    if (!ct->Transform(1, &p.x, &p.y) || !std::isfinite(p.x) || !std::isfinite(p.y)) {
      throw Error(p.name + " (" + formatNumber(x0) + ", " + formatNumber(y0) +
                  ") cannot be converted to the raster's CRS");
    }
  }
}

std::unique_ptr<OGRSpatialReference> srsOf(const std::string& srs) {
  return srs.empty() ? nullptr : crsFromUser(srs, "--srs");
}

// Text lines "x y [height]" (spaces, tabs or commas; '#' starts a comment), in --srs or the
// raster's CRS; a height, when given, overrides --observer-height.
std::vector<Observer> observersFromText(const ViewshedOptions& o) {
  std::ifstream in(o.observersFile);
  if (!in) throw Error(o.observersFile + ": cannot open");
  std::vector<Observer> points;
  std::string line;
  for (std::size_t number = 1; std::getline(in, line); ++number) {
    const std::string text = line.substr(0, line.find('#'));
    std::vector<double> fields;
    std::size_t i = 0;
    while (i < text.size()) {
      while (i < text.size() && (std::isspace(static_cast<unsigned char>(text[i])) || text[i] == ',')) ++i;
      if (i == text.size()) break;
      std::size_t j = i;
      while (j < text.size() && !std::isspace(static_cast<unsigned char>(text[j])) && text[j] != ',') ++j;
      double v = 0;
      const auto [end, ec] = std::from_chars(text.data() + i, text.data() + j, v);
      if (ec != std::errc() || end != text.data() + j || !std::isfinite(v))
        fields.assign(4, 0);  // not a number
      else
        fields.push_back(v);
      i = j;
    }
    if (fields.empty()) continue;
    const std::string name = o.observersFile + ":" + std::to_string(number);
    if (fields.size() < 2 || fields.size() > 3) {
      std::string message = name + ": expected 'x y [height]' (numbers), got '";
      message += line;
      message += '\'';
      throw Error(message);
    }
    points.push_back({fields[0], fields[1], fields.size() == 3 ? fields[2] : o.observerHeight, name});
  }
  if (points.empty()) throw Error(o.observersFile + ": no observers in it");
  return points;
}

// Observers from --observers: an OGR point layer (GeoPackage, GeoJSON, Shapefile, FlatGeobuf, CSV
// with x/y, lon/lat or easting/northing columns...) in its own CRS, each feature's height from
// the field --height-field when it has one (else --observer-height); anything else is text.
std::vector<Observer> readObservers(const ViewshedOptions& o, const DemTerrain& dem) {
  const char* csv[] = {"X_POSSIBLE_NAMES=x,lon,long,longitude,easting", "Y_POSSIBLE_NAMES=y,lat,latitude,northing",
                       "AUTODETECT_TYPE=YES", nullptr};
  std::unique_ptr<GDALDataset> ds;
  {
    CPLPushErrorHandler(CPLQuietErrorHandler);  // (a text file is not a layer: no noise about it)
    const char* const csvDriver[] = {"CSV", nullptr};
    const bool isCsv =
        o.observersFile.size() > 4 && !strcasecmp(o.observersFile.c_str() + o.observersFile.size() - 4, ".csv");
    ds.reset(GDALDataset::FromHandle(GDALOpenEx(o.observersFile.c_str(), GDAL_OF_VECTOR | GDAL_OF_READONLY,
                                                isCsv ? csvDriver : nullptr, isCsv ? csv : nullptr, nullptr)));
    CPLPopErrorHandler();
  }
  std::vector<Observer> points;
  const auto text = srsOf(o.srs);
  if (!ds || ds->GetLayerCount() == 0) {
    points = observersFromText(o);
    toRasterCrs(text.get(), dem, points, "--observers " + o.observersFile);
    return points;
  }
  OGRLayer* layer = ds->GetLayer(0);
  const int heightField = layer->GetLayerDefn()->GetFieldIndex(o.heightField.c_str());
  layer->ResetReading();
  for (OGRFeatureUniquePtr f(layer->GetNextFeature()); f; f.reset(layer->GetNextFeature())) {
    const std::string name = o.observersFile + " feature " + std::to_string(f->GetFID());
    const OGRGeometry* g = f->GetGeometryRef();
    if (!g || wkbFlatten(g->getGeometryType()) != wkbPoint) {
      throw Error(name +
                  ": not a point (observers are points; a CSV needs x/y, lon/lat or easting/northing "
                  "columns)");
    }
    const auto* p = g->toPoint();
    double height = o.observerHeight;
    if (heightField >= 0 && f->IsFieldSetAndNotNull(heightField)) height = f->GetFieldAsDouble(heightField);
    points.push_back({p->getX(), p->getY(), height, name});
  }
  if (points.empty()) throw Error(o.observersFile + ": no observers in its first layer");
  const OGRSpatialReference* layerSrs = layer->GetSpatialRef();
  toRasterCrs(layerSrs ? layerSrs : text.get(), dem, points, "--observers " + o.observersFile);
  return points;
}

void checkOptions(const ViewshedOptions& o, const std::string& format) {
  if (o.output.empty()) throw Error("an output file is needed: -o OUT");
  if (o.observer.has_value() == !o.observersFile.empty()) {
    throw Error("give one observer (--observer X,Y) or a file of them (--observers FILE)");
  }
  if (!o.whichFile.empty() && o.observersFile.empty()) {
    throw Error("--which FILE records which of --observers see each pixel; give --observers");
  }
  if (!o.whichFile.empty() && (sameFile(o.whichFile, o.output) || sameFile(o.whichFile, o.source) ||
                               (!o.png.empty() && sameFile(o.whichFile, o.png)))) {
    throw Error("--which " + o.whichFile + " names the input or another output; give a file of its own");
  }
  if (o.refraction != 0 && !o.observersFile.empty()) {
    throw Error("--refraction takes one observer (--observer); it is not applied to --observers");
  }
  const int values[4] = {o.visibleValue, o.hiddenValue, o.nodataValue, o.outOfRangeValue};
  for (int v : values) {
    if (v < 0 || v > 255) throw Error("output values must be 0..255, got " + std::to_string(v));
  }
  for (int a = 0; a < 4; ++a) {
    for (int b = a + 1; b < 4; ++b) {
      if (values[a] == values[b]) {
        throw Error("--visible-value " + std::to_string(o.visibleValue) + ", --invisible-value " +
                    std::to_string(o.hiddenValue) + ", --nodata-value " + std::to_string(o.nodataValue) +
                    " and --out-of-range-value " + std::to_string(o.outOfRangeValue) +
                    " must differ, or the pixels could not be told apart");
      }
    }
  }
  if (format == "VRT" || format == "MEM") {
    throw Error(o.output + ": the " + format +
                " format holds no pixels of its own; write a GeoTIFF (.tif) or another format that stores them");
  }
  for (const std::string* path : {&o.output, &o.png}) {
    if (!path->empty() && sameFile(*path, o.source)) throw Error(*path + " is the input DEM; give another output name");
  }
  if (!o.png.empty() && sameFile(o.png, o.output)) throw Error("--png and -o name the same file");
}

}  // namespace

namespace {

// Where the DEM was read and placed: the pieces both kinds of run share.
struct Run {
  std::string format;
  DemTerrain dem;
  FrameOptions frame;
};

// The values of a single observer's viewshed, its summary, its raster.
void writeOne(const ViewshedOptions& o, Run& run, std::ostream& out, OutputStage& stage) {
  std::vector<Observer> at{{(*o.observer)[0], (*o.observer)[1], o.observerHeight, "--observer"}};
  toRasterCrs(srsOf(o.srs).get(), run.dem, at, "--observer");
  qota::ViewshedOptions v;
  v.observerX = at[0].x, v.observerY = at[0].y;
  v.observerHeight = o.observerHeight, v.targetHeight = o.targetHeight, v.maxDistance = o.maxDistance;
  v.refraction = o.refraction;
  v.frame = run.frame;
  v.index = o.index;
  v.sweep = !o.perPixel;
  // The viewshed takes the DEM's heights over (a raster of doubles not copied) unless the
  // preview's hillshade needs them after it.
  const Viewshed seen = o.png.empty() ? qota::viewshed(std::move(run.dem), v, termProgress(o.quiet, 0, 1))
                                      : qota::viewshed(run.dem, v, termProgress(o.quiet, 0, 1));
  if (!o.quiet) {
    out << "frame: " << seen.frameDescription << '\n'
        << "observer: " << formatNumber(v.observerX) << ", " << formatNumber(v.observerY) << ", "
        << formatNumber(o.observerHeight) << " m above the surface at " << formatNumber(seen.surface, 3) << " m\n"
        << "visible: " << seen.visible << " of " << seen.tested << " pixels tested ("
        << formatNumber(seen.tested ? 100.0 * seen.visible / seen.tested : 0.0, 2) << " %)\n"
        << "decided: " << seen.swept << " by the sweep, " << seen.oneByOne << " one by one ("
        << (seen.method == "walk" ? "walked over the squares under each line of sight" : "through the quadtree")
        << ")\n";
  }
  std::vector<double> values(seen.sight.size());
  for (std::size_t i = 0; i < values.size(); ++i) {
    const Sight s = seen.sight[i];
    values[i] = s == Sight::Visible  ? o.visibleValue
                : s == Sight::Hidden ? o.hiddenValue
                : s == Sight::NoData ? o.nodataValue
                                     : o.outOfRangeValue;
  }
  RasterWrite w{o.output,
                run.format,
                o.creationOptions,
                true,
                double(o.nodataValue),
                true,
                {{"QOTA_TOOL", "viewshed"},
                 {"QOTA_SOURCE", o.source},
                 {"QOTA_BAND", std::to_string(run.dem.band)},
                 {"QOTA_FRAME", seen.frameDescription},
                 {"QOTA_OBSERVER", formatNumber(v.observerX) + "," + formatNumber(v.observerY)},
                 {"QOTA_OBSERVER_HEIGHT", formatNumber(o.observerHeight)},
                 {"QOTA_TARGET_HEIGHT", formatNumber(o.targetHeight)},
                 {"QOTA_MAX_DISTANCE", formatNumber(o.maxDistance)},
                 {"QOTA_REFRACTION", formatNumber(o.refraction)},
                 {"QOTA_FILL_VOIDS", o.fillVoids ? kFillVoidsText : "no"},
                 {"QOTA_VALUES", "visible=" + std::to_string(o.visibleValue) + ",invisible=" +
                                     std::to_string(o.hiddenValue) + ",nodata=" + std::to_string(o.nodataValue) +
                                     ",out_of_range=" + std::to_string(o.outOfRangeValue)}}};
  w.bandDescription = "viewshed";
  writeRaster(w, run.dem, values, stage);
  if (!o.png.empty()) {
    std::vector<int> classes(seen.sight.size());
    for (std::size_t i = 0; i < classes.size(); ++i) {
      const Sight s = seen.sight[i];
      classes[i] = s == Sight::Visible ? 0 : s == Sight::Hidden ? 1 : s == Sight::NoData ? -1 : 2;
    }
    FrameBasis basis;
    const LocalFrame frame = localFrame(run.dem, run.frame, basis, /*triangles=*/false);  // (a hillshade's)
    writeCategoryPreview(o.png, frame.width, frame.height, hillshade(frame, kPreviewLight), classes,
                         {{"visible", {255, 170, 0}, 0.7},
                          {"not visible", {255, 255, 255}, 0.0},
                          {"beyond --max-distance", {180, 180, 180}, 0.6}},
                         std::filesystem::path(o.source).filename().string() + ": seen from " +
                             formatNumber(v.observerX) + ", " + formatNumber(v.observerY) + ", " +
                             formatNumber(o.observerHeight) + " m up",
                         stage);
  }
}

// How many of --observers see each pixel: UInt16 (UInt32 from 65535 observers on), nodata the
// type's largest value.
void writeCounts(const ViewshedOptions& o, const Run& run, std::ostream& out, OutputStage& stage) {
  const std::vector<Observer> observers = readObservers(o, run.dem);
  if (!o.whichFile.empty() && observers.size() > 31) {
    throw Error("--which keeps a bit for each observer, at most 31 (a UInt32 with its nodata); " + o.observersFile +
                " has " + std::to_string(observers.size()));
  }
  CumulativeOptions c;
  c.targetHeight = o.targetHeight, c.maxDistance = o.maxDistance, c.frame = run.frame, c.index = o.index;
  c.which = !o.whichFile.empty();
  c.sweep = !o.perPixel;
  if (!o.quiet) out << "observers: " << observers.size() << " from " << o.observersFile << '\n';
  const CumulativeViewshed seen = cumulativeViewshed(run.dem, observers, c, termProgress(o.quiet, 0, 1));
  const bool wide = observers.size() >= 65535;
  const double nodata = wide ? 4294967295.0 : 65535.0;
  std::vector<double> values(seen.count.size()), counts(seen.count.size());
  std::uint32_t most = 0, seenAny = 0;
  for (std::uint32_t k : seen.count) most = std::max(most, k);
  for (std::size_t i = 0; i < values.size(); ++i) {
    values[i] = seen.valid[i] ? seen.count[i] : nodata;
    counts[i] = seen.valid[i] ? seen.count[i] : std::numeric_limits<double>::quiet_NaN();
    seenAny += seen.valid[i] && seen.count[i] > 0;
  }
  if (!o.quiet) {
    out << "frame: " << seen.frameDescription << '\n'
        << "seen by at least one: " << seenAny << " pixels; by the most: " << most << " observers\n";
  }
  RasterWrite w{o.output,
                run.format,
                o.creationOptions,
                true,
                nodata,
                true,
                {{"QOTA_TOOL", "viewshed"},
                 {"QOTA_SOURCE", o.source},
                 {"QOTA_BAND", std::to_string(run.dem.band)},
                 {"QOTA_FRAME", seen.frameDescription},
                 {"QOTA_OBSERVERS", o.observersFile},
                 {"QOTA_OBSERVER_COUNT", std::to_string(observers.size())},
                 {"QOTA_FILL_VOIDS", o.fillVoids ? kFillVoidsText : "no"},
                 {"QOTA_TARGET_HEIGHT", formatNumber(o.targetHeight)},
                 {"QOTA_MAX_DISTANCE", formatNumber(o.maxDistance)},
                 {"QOTA_VALUES", "count of the observers that see the pixel"}},
                wide ? "UInt32" : "UInt16"};
  w.bandDescription = "observers that see the pixel";
  writeRaster(w, run.dem, values, stage);
  if (!o.whichFile.empty()) {
    // The smallest type with a value left for nodata above every bitset.
    const std::size_t bits = observers.size() < 8 ? 8 : observers.size() < 16 ? 16 : 32;
    const double none = std::ldexp(1.0, static_cast<int>(bits)) - 1;
    std::vector<double> which(seen.which.size());
    for (std::size_t i = 0; i < which.size(); ++i) which[i] = seen.valid[i] ? static_cast<double>(seen.which[i]) : none;
    std::vector<std::pair<std::string, std::string>> metadata{{"QOTA_TOOL", "viewshed"},
                                                              {"QOTA_SOURCE", o.source},
                                                              {"QOTA_FRAME", seen.frameDescription},
                                                              {"QOTA_OBSERVERS", o.observersFile},
                                                              {"QOTA_TARGET_HEIGHT", formatNumber(o.targetHeight)},
                                                              {"QOTA_MAX_DISTANCE", formatNumber(o.maxDistance)},
                                                              {"QOTA_VALUES", "bit k set: observer k sees the pixel"}};
    for (std::size_t k = 0; k < observers.size(); ++k) {
      metadata.emplace_back("QOTA_BIT_" + std::to_string(k), observers[k].name + " (" + formatNumber(observers[k].x) +
                                                                 ", " + formatNumber(observers[k].y) + ")");
    }
    RasterWrite bitsWrite{o.whichFile, driverForPath(o.whichFile),
                          {},          true,
                          none,        true,
                          metadata,    bits == 8 ? "Byte" : bits == 16 ? "UInt16" : "UInt32"};
    bitsWrite.bandDescription = "which observers see the pixel (a bit each)";
    writeRaster(bitsWrite, run.dem, which, stage);
  }
  if (!o.png.empty()) {
    FrameBasis basis;
    const LocalFrame frame = localFrame(run.dem, run.frame, basis, /*triangles=*/false);  // (a hillshade's)
    writeRampPreview(o.png, frame.width, frame.height, hillshade(frame, kPreviewLight), counts, 0, most, "observers",
                     std::filesystem::path(o.source).filename().string() + ": how many of " +
                         std::to_string(observers.size()) + " observers see each pixel",
                     stage);
  }
}

}  // namespace

int viewshed(const ViewshedOptions& given, std::ostream& out, std::ostream& err) {
  try {
    ViewshedOptions o = given;
    o.flat = flatByMapping(o.mapping, o.flat, "viewshed", "draws no line of sight on a DEM's grid");
    for (const std::string* path : {&o.output, &o.png, &o.whichFile}) {
      if (!path->empty()) OutputStage::checkTarget(*path);
    }
    Run run;
    run.format = o.output.empty() ? "" : o.format.empty() ? driverForPath(o.output) : o.format;
    checkOptions(o, run.format);
    const std::uint64_t mostValue =
        o.observersFile.empty() ? std::max({o.visibleValue, o.hiddenValue, o.nodataValue, o.outOfRangeValue}) : 65535;
    for (const std::string& warning : checkCreationOptions(run.format, o.creationOptions, true, mostValue)) {
      err << "qota viewshed: warning: GDAL: " << warning << '\n';
    }
    DemOptions demOptions;
    demOptions.band = o.band;
    demOptions.lonLatAsCartesian = true;  // read as lon/lat: the frame puts it on its ellipsoid
    // The sweep (a flat frame: --flat, or a raster without CRS; not --per-pixel) and the walk (on
    // the ellipsoid) keep no quadtree: a cost of their own, a tenth of a quadtree's or less. An
    // observer neither can take (on the surface, outside the outermost pixel centres, a raster too
    // far from flat to walk) is checked again before its quadtree is built (qota::viewshed).
    memory::PerItem extra;
    if (!o.png.empty()) extra = extra + memory::kPreview;
    if (!o.observersFile.empty()) extra = extra + memory::kCounts;
    if (!o.whichFile.empty()) extra = extra + memory::kWhich;
    const memory::PerItem swept = memory::kSweptLinesOfSight + extra, quadtree = memory::kLinesOfSight + extra;
    const memory::PerItem walked = memory::kWalkedLinesOfSight + extra;
    demOptions.then = o.perPixel ? quadtree : o.flat ? swept : walked;
    demOptions.thenWithoutCrs = o.perPixel ? quadtree : swept;
    demOptions.fillVoids = o.fillVoids ? kFillVoidsPixels : 0;
    demOptions.triangles = false;  // (the frame triangulates the grid from the heights)
    demOptions.vertices = false;
    run.dem = loadDem(o.source, demOptions);
    if (!o.quiet && o.fillVoids) {
      out << "voids: " << run.dem.filledPixels << " pixels filled (GDAL's fill-nodata), " << run.dem.nodataPixels
          << " left\n";
    }
    run.frame = frameOptionsOf(o);
    if (!o.quiet) out << "qota viewshed: " << o.source << " -> " << o.output << " (" << run.format << ")\n";
    OutputStage stage;
    o.observersFile.empty() ? writeOne(o, run, out, stage) : writeCounts(o, run, out, stage);
    stage.commit();
    if (!o.quiet) {
      out << "written: " << o.output << (o.png.empty() ? "" : " and " + o.png)
          << (o.whichFile.empty() ? "" : " and " + o.whichFile) << '\n';
    }
    return 0;
  } catch (...) {
    return reportFailure("viewshed", err);
  }
}

}  // namespace qota::tools
