// qota info: what a source is, without building anything (a raster's facts as GDAL and qota read
// them, the memory each tool would take), and with --tree the statistics of its quadtree.
#include <GeographicLib/Geodesic.hpp>
#include <gdal_priv.h>
#include <ogr_spatialref.h>

#include <chrono>
#include <cmath>
#include <iostream>
#include <limits>
#include <nlohmann/json.hpp>

#include "qota/dem.hpp"
#include "qota/error.hpp"
#include "qota/geoid.hpp"
#include "qota/mapping_registry.hpp"
#include "qota/memory_budget.hpp"
#include "qota/treefile.hpp"
#include "qota_tools.hpp"
#include "shadow_parts.hpp"
#include "text_output.hpp"

namespace qota::tools {
namespace {

using Json = nlohmann::ordered_json;

// The facts in the order found, each written once and printed two ways: "label: text" lines for
// people, or one JSON object for scripts (the key is the label in snake case: "pixel size on
// the ground (m)" is pixel_size_on_the_ground_m).
class Facts {
 public:
  // key: the JSON key when it is not the label's (a label for people, a key with its unit).
  void add(const std::string& label, Json value, std::string text = {}, std::string key = {}) {
    if (text.empty()) text = textOf(value);
    if (key.empty()) key = keyOf(label);
    facts_.push_back({label, std::move(key), std::move(value), std::move(text)});
  }
  void print(std::ostream& out, bool json) const {
    if (!json) {
      for (const Fact& f : facts_) out << f.label << ": " << f.text << '\n';
      return;
    }
    Json all = Json::object();
    for (const Fact& f : facts_) all[f.key] = f.value;
    out << all.dump(2) << '\n';
  }

  static std::string textOf(const Json& v) {
    if (v.is_null()) return "none";
    if (v.is_string()) return v.get<std::string>();
    if (v.is_boolean()) return v.get<bool>() ? "yes" : "no";
    if (v.is_number_integer()) return std::to_string(v.get<std::int64_t>());
    if (v.is_number_unsigned()) return std::to_string(v.get<std::uint64_t>());
    if (v.is_number()) return formatNumber(v.get<double>());
    if (v.is_array()) {
      std::string s;
      for (const Json& e : v) s += (s.empty() ? "" : " ") + textOf(e);
      return s;
    }
    return v.dump();
  }

 private:
  struct Fact {
    std::string label, key;
    Json value;
    std::string text;
  };
  static std::string keyOf(const std::string& label) {
    std::string key;
    for (char c : label) {
      if (std::isalnum(static_cast<unsigned char>(c))) {
        key += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
      } else if (!key.empty() && key.back() != '_') {
        key += '_';
      }
    }
    while (!key.empty() && key.back() == '_') key.pop_back();
    return key;
  }
  std::vector<Fact> facts_;
};

// A number as JSON: null for NaN or infinity, which JSON cannot hold.
Json number(double v) { return std::isfinite(v) ? Json(v) : Json(nullptr); }

std::string crsName(const OGRSpatialReference& srs) {
  const char* name = srs.GetName();
  const char* auth = srs.GetAuthorityName(nullptr);
  const char* code = srs.GetAuthorityCode(nullptr);
  std::string s = name ? name : "unnamed";
  if (auth && code) s += std::string(" (") + auth + ':' + code + ')';
  return s;
}

// The CRS, the extent in it and in longitude/latitude, and a pixel's size on the ground at the
// raster's centre: its neighbours' centres through the CRS's geographic CRS and GeographicLib's
// geodesics on the CRS's ellipsoid (true distances, a projection's scale factor included).
void crsFacts(const DemTerrain& dem, Facts& f) {
  const auto& g = dem.geotransform;
  double xs[4], ys[4];
  const double cols[4] = {0, static_cast<double>(dem.width), 0, static_cast<double>(dem.width)};
  const double rows[4] = {0, 0, static_cast<double>(dem.height), static_cast<double>(dem.height)};
  for (int i = 0; i < 4; ++i) {
    xs[i] = g[0] + cols[i] * g[1] + rows[i] * g[2];
    ys[i] = g[3] + cols[i] * g[4] + rows[i] * g[5];
  }
  const double xmin = *std::min_element(xs, xs + 4), xmax = *std::max_element(xs, xs + 4);
  const double ymin = *std::min_element(ys, ys + 4), ymax = *std::max_element(ys, ys + 4);
  f.add("geotransform", Json(dem.geotransform));
  f.add("extent", Json::array({xmin, ymin, xmax, ymax}),
        "xmin " + formatNumber(xmin) + " ymin " + formatNumber(ymin) + " xmax " + formatNumber(xmax) + " ymax " +
            formatNumber(ymax));
  f.add("pixel size", Json::array({std::hypot(g[1], g[4]), std::hypot(g[2], g[5])}));

  if (dem.crsWkt.empty()) {
    f.add("crs", nullptr);
    return;
  }
  OGRSpatialReference srs;
  srs.importFromWkt(dem.crsWkt.c_str());
  if (!srs.GetAuthorityCode(nullptr)) srs.AutoIdentifyEPSG();  // e.g. an unnamed UTM zone
  f.add("crs", crsName(srs));
  f.add("crs kind", srs.IsGeographic() ? "geographic" : srs.IsProjected() ? "projected" : "other");
  if (srs.IsProjected()) {
    const char* unit = nullptr;
    srs.GetLinearUnits(&unit);
    f.add("crs unit", unit ? unit : "unknown");
  }

  std::unique_ptr<OGRSpatialReference> geographic(srs.CloneGeogCS());
  if (!geographic) return;
  srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  geographic->SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  std::unique_ptr<OGRCoordinateTransformation> toLonLat;
  if (!srs.IsGeographic()) {
    toLonLat.reset(OGRCreateCoordinateTransformation(&srs, geographic.get()));
    if (!toLonLat) return;
    double w = 0, s = 0, e = 0, n = 0;
    if (toLonLat->TransformBounds(xmin, ymin, xmax, ymax, &w, &s, &e, &n, 21)) {
      f.add("extent (lon/lat)", Json::array({w, s, e, n}),
            "west " + formatNumber(w) + " south " + formatNumber(s) + " east " + formatNumber(e) + " north " +
                formatNumber(n));
    }
  }
  OGRErr e1 = OGRERR_NONE, e2 = OGRERR_NONE;
  const double a = srs.GetSemiMajor(&e1), invf = srs.GetInvFlattening(&e2);
  if (e1 != OGRERR_NONE || e2 != OGRERR_NONE) return;
  const GeographicLib::Geodesic geod(a, invf > 0 ? 1.0 / invf : 0.0);
  const double cc = (dem.width - 1) / 2.0, cr = (dem.height - 1) / 2.0;
  std::array<std::array<double, 2>, 3> p = {dem.pixelCentre(cc, cr), dem.pixelCentre(cc + 1, cr),
                                            dem.pixelCentre(cc, cr + 1)};
  for (auto& q : p) {
    if (toLonLat && !toLonLat->Transform(1, &q[0], &q[1])) return;
  }
  double sx = 0, sy = 0;
  geod.Inverse(p[0][1], p[0][0], p[1][1], p[1][0], sx);
  geod.Inverse(p[0][1], p[0][0], p[2][1], p[2][0], sy);
  f.add("pixel size on the ground (m)", Json::array({sx, sy}), formatNumber(sx, 2) + " x " + formatNumber(sy, 2));
}

// The lowest and highest heights of a band as qota reads them (scale and offset applied; nodata,
// NaN and infinite values left out), read by strips of whole rows.
struct HeightRange {
  double lo = std::numeric_limits<double>::infinity(), hi = -std::numeric_limits<double>::infinity();
  std::uint64_t valid = 0, voids = 0;
};
HeightRange heightRange(const std::string& path, int band) {
  const DemWindows windows(path, {.band = band, .lonLatAsCartesian = true});
  const DemTerrain& d = windows.dem();
  const int rows = std::max(1, std::min(d.height, (1 << 22) / std::max(d.width, 1)));
  HeightRange r;
  std::vector<double> z;
  for (int row = 0; row < d.height; row += rows) {
    const int h = std::min(rows, d.height - row);
    windows.read(0, row, d.width, h, z);
    for (double v : z) {
      if (std::isnan(v)) {
        ++r.voids;
        continue;
      }
      ++r.valid;
      r.lo = std::min(r.lo, v), r.hi = std::max(r.hi, v);
    }
  }
  return r;
}

// Every band as GDAL describes it, and with `stats` its height range.
void bandFacts(GDALDataset& ds, const std::string& path, bool stats, Facts& f) {
  f.add("bands", ds.GetRasterCount());
  for (int b = 1; b <= ds.GetRasterCount(); ++b) {
    GDALRasterBand* band = ds.GetRasterBand(b);
    Json j = Json::object();
    j["type"] = GDALGetDataTypeName(band->GetRasterDataType());
    std::string text = j["type"].get<std::string>();
    const std::string unit = band->GetUnitType() ? band->GetUnitType() : "";
    j["unit"] = unit.empty() ? Json(nullptr) : Json(unit);
    if (!unit.empty()) text += ", unit " + unit;
    int has = FALSE;
    const double nodata = band->GetNoDataValue(&has);
    j["nodata"] = has ? number(nodata) : Json(nullptr);
    if (has) text += ", nodata " + formatNumber(nodata);
    int hasScale = FALSE, hasOffset = FALSE;
    const double scale = band->GetScale(&hasScale), offset = band->GetOffset(&hasOffset);
    j["scale"] = hasScale ? scale : 1.0;
    j["offset"] = hasOffset ? offset : 0.0;
    if ((hasScale && scale != 1) || (hasOffset && offset != 0)) {
      text += ", scale " + formatNumber(scale) + ", offset " + formatNumber(offset);
    }
    const std::string description = band->GetDescription() ? band->GetDescription() : "";
    if (!description.empty()) j["description"] = description, text += ", '" + description + "'";
    if (stats) {
      try {
        const HeightRange r = heightRange(path, b);
        j["valid_pixels"] = r.valid;
        j["void_pixels"] = r.voids;
        if (r.valid) {
          j["min"] = r.lo, j["max"] = r.hi;
          text += ", heights " + formatNumber(r.lo) + " to " + formatNumber(r.hi);
        }
        text += ", " + std::to_string(r.voids) + " void pixels";
      } catch (const Error& e) {
        j["not_heights"] = e.what();
        text += " (not heights: " + std::string(e.what()) + ")";
      }
    }
    f.add("band " + std::to_string(b), j, text);
  }
  if (!stats) f.add("height range", nullptr, "not computed (--stats reads every pixel)");
}

// What the heights are and are over: their unit, the vertical CRS, and the reference the tools
// that place a DEM on its ellipsoid (shadow, viewshed, --mapping geodetic) take.
void heightFacts(const DemTerrain& dem, const SourceOptions& so, Facts& f) {
  const VerticalUnit& u = dem.verticalUnit;
  f.add("vertical unit", u.known() ? Json(u.name) : Json(nullptr),
        u.known() ? u.name + " (" + formatNumber(u.metresPerUnit) + " m)" : "none stated (metres assumed)");
  f.add("metres per unit", u.metresPerUnit);
  const VerticalReference& v = dem.verticalReference;
  std::string vertical = v.name.empty() ? (v.ellipsoidal ? "geographic 3D (heights over the ellipsoid)" : "none")
                                        : v.name + (v.epsg ? " (EPSG:" + std::to_string(v.epsg) + ")" : "");
  f.add("vertical crs", v.name.empty() && !v.ellipsoidal ? Json(nullptr) : Json(vertical), vertical);
  if (dem.crsWkt.empty()) {
    f.add("heights over", nullptr, "no CRS: heights as they are (a map)");
    return;
  }
  try {
    const HeightReference r = heightReferenceOf(dem, so.heightRef);
    f.add("heights over", Json{{"name", r.name}, {"grid", r.grid}, {"why", r.why}, {"assumed", r.assumed}},
          r.describe());
  } catch (const Error& e) {
    f.add("heights over", Json{{"error", e.what()}}, std::string("unknown: ") + e.what());
  }
}

// The memory each tool would take on this raster (the same estimates they refuse by), and the
// memory available now.
void memoryFacts(const DemTerrain& dem, const SourceOptions& so, Facts& f) {
  const std::uint64_t w = static_cast<std::uint64_t>(dem.width), h = static_cast<std::uint64_t>(dem.height);
  const std::uint64_t v = w * h, t = w > 1 && h > 1 ? 2 * (w - 1) * (h - 1) : 0;
  const bool curved = !mappingEntry(so.mapping).map;
  const std::uint64_t tree = memory::kProcessBase + memory::kDemMesh.bytes(v, t) +
                             (curved ? memory::kCurvedIndex : memory::kCartesianIndex).bytes(v, t);
  // (qota viewshed reads the heights alone: on the ellipsoid each line of sight is walked over the
  // squares under it; a flat frame's (--flat, or a raster without CRS) are swept; neither builds a
  // quadtree.)
  const std::uint64_t sight = memory::kProcessBase + (memory::kDemHeights + memory::kWalkedLinesOfSight).bytes(v, t);
  const std::uint64_t swept = memory::kProcessBase + (memory::kDemHeights + memory::kSweptLinesOfSight).bytes(v, t);
  std::uint64_t shadow = 0;
  try {
    ShadowOptions s;
    s.source = so.source, s.band = dem.band, s.azimuth = 315, s.altitude = 45;
    shadow = wholeEstimate(s, memory::kProcessBase);
  } catch (const Error&) {
    // A raster shadow cannot read (a unit that is not a length): no estimate.
  }
  const std::uint64_t available = memory::availableBytes();
  f.add("grid triangles", t);
  f.add("memory for --tree and build", tree, memory::gib(tree), "memory_tree_bytes");
  f.add("memory for shadow", shadow ? Json(shadow) : Json(nullptr),
        shadow ? memory::gib(shadow) + " (the whole raster; by tiles when more than available)" : "unknown",
        "memory_shadow_bytes");
  const bool flat = dem.crsWkt.empty();  // (its frame is flat without --flat)
  f.add("memory for viewshed", flat ? swept : sight,
        memory::gib(flat ? swept : sight) + (flat ? " (a flat frame: the sweep)" : ""), "memory_viewshed_bytes");
  f.add("memory for viewshed --flat", swept, memory::gib(swept) + " (the sweep)", "memory_viewshed_flat_bytes");
  f.add("memory for sample", nullptr, "streams by blocks (GDAL's block cache)", "memory_sample_bytes");
  f.add("memory available", available ? Json(available) : Json(nullptr), available ? memory::gib(available) : "unknown",
        "memory_available_bytes");
}

// The quadtree's statistics (the paper's Table 4 and the tree's shape) and memory.
void treeFacts(const IndexStats& s, double seconds, bool loaded, Facts& f) {
  const QuadtreeStats& t = s.tree;
  f.add("polygons", s.polygons);
  f.add("triangles", s.triangles);
  f.add("nodes", t.nodes);
  f.add("leaves", t.leaves);
  f.add("empty leaves", t.emptyLeaves);
  f.add("depth", t.depth);
  f.add("leaf references", t.references);
  f.add("max polygons per leaf", t.maxLeafItems);
  f.add("mean polygons per leaf", t.meanLeafItems, formatNumber(t.meanLeafItems, 3));
  f.add("average tests per query", t.averageTests, formatNumber(t.averageTests, 3));
  f.add("memory (bytes)", s.memoryBytes);
  f.add("memory (MB)", static_cast<double>(s.memoryBytes) / 1e6,
        formatNumber(static_cast<double>(s.memoryBytes) / 1e6, 3));
  const double perTriangle = s.triangles ? static_cast<double>(s.memoryBytes) / static_cast<double>(s.triangles) : 0.0;
  f.add("bytes per triangle", perTriangle, formatNumber(perTriangle, 1));
  f.add(loaded ? "load time (s)" : "build time (s)", seconds, formatNumber(seconds, 3));
}

double secondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// A tree file, a mesh, or a raster's tree in a curved mapping: what it was built from, its
// mapping and its tree, and how long loading (or building) took.
void indexFacts(const SourceOptions& so, Facts& f) {
  const bool treeFile = isTreeFile(so.source);
  const auto start = std::chrono::steady_clock::now();
  const TreeFile tree = openIndex(so);
  const double seconds = secondsSince(start);
  if (treeFile) {
    f.add("source", so.source);
    f.add("driver", "qota tree file");
    f.add("built from", tree.source.path.empty() ? Json(nullptr) : Json(tree.source.path),
          tree.source.path.empty() ? "unknown" : tree.source.path);
    if (tree.source.width > 0) {
      f.add("size", Json::array({tree.source.width, tree.source.height}),
            std::to_string(tree.source.width) + " x " + std::to_string(tree.source.height));
    }
    if (!tree.source.heightRef.empty()) f.add("heights over", tree.source.heightRef);
  } else if (!isRaster(so.source)) {
    f.add("source", so.source);
    f.add("driver", "mesh");
  }
  std::visit(
      [&](const auto& index) {
        f.add("mapping", index.mapping().describe());
        treeFacts(index.stats(), seconds, treeFile, f);
      },
      tree.index);
}

// A raster's --tree in the default (cartesian) mapping: the index in the raster's own x, y
// (degrees for a lon/lat raster: the quadtree works in (u, v) whatever their unit).
void mapTreeFacts(const SourceOptions& so, Facts& f) {
  const DemTerrain dem = loadDem(so.source, {.band = so.band, .lonLatAsCartesian = true, .fillVoids = so.fillVoids});
  const auto start = std::chrono::steady_clock::now();
  const CartesianIndex index(dem.mesh, dem.mapping, so.index);
  const double seconds = secondsSince(start);
  f.add("mapping", index.mapping().describe());
  f.add("walls left out", index.stats().leftOut);
  if (so.fillVoids > 0) f.add("voids filled", dem.filledPixels);
  f.add("max poly", so.index.tree.maxPoly);
  f.add("max depth", so.index.tree.maxDepth);
  treeFacts(index.stats(), seconds, false, f);
}

// A raster, read as GDAL describes it: nothing built, no pixel read unless `stats`.
void rasterFacts(const InfoOptions& o, Facts& f) {
  const SourceOptions& so = o.source;
  ensureGdalRegistered();
  const DemTerrain dem = describeDem(so.source, {.band = so.band ? so.band : 1, .lonLatAsCartesian = true});
  std::unique_ptr<GDALDataset> ds(
      GDALDataset::Open(so.source.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY, nullptr, nullptr, nullptr));
  if (!ds) throw Error(so.source + ": cannot be opened as a raster");
  f.add("source", dem.path);
  const char* longName = ds->GetDriver()->GetMetadataItem(GDAL_DMD_LONGNAME);
  f.add("driver", dem.driver, longName ? dem.driver + " (" + longName + ")" : dem.driver);
  f.add("size", Json::array({dem.width, dem.height}), std::to_string(dem.width) + " x " + std::to_string(dem.height));
  bandFacts(*ds, so.source, o.stats, f);
  f.add("heights band", dem.band);
  f.add("nodata", dem.nodata ? number(*dem.nodata) : Json(nullptr),
        dem.nodata ? formatNumber(*dem.nodata) : std::string("none"));
  heightFacts(dem, so, f);
  crsFacts(dem, f);
  memoryFacts(dem, so, f);
}

bool buildsFromRasterAsMap(const SourceOptions& so) {
  return mappingEntry(so.mapping).map && so.heightRef.empty() && !so.origin && so.radius == 0 && so.length == 0;
}

}  // namespace

int info(const InfoOptions& options, std::ostream& out, std::ostream& err) {
  try {
    const SourceOptions& so = options.source;
    requireSource(so.source);
    Facts f;
    if (isTreeFile(so.source) || !isRaster(so.source)) {
      indexFacts(so, f);  // a tree file or a mesh is read whole whatever is asked
    } else {
      requireMappingOptions(so);
      rasterFacts(options, f);
      if (!options.tree) {
        const std::string mapping = so.mapping.empty() ? "cartesian" : so.mapping;
        f.add("mapping", mapping, mapping + " (--tree builds its quadtree and prints the statistics)");
      } else {
        try {
          buildsFromRasterAsMap(so) ? mapTreeFacts(so, f) : indexFacts(so, f);
        } catch (const Error& e) {
          throw Error(std::string(e.what()) +
                      ". Without --tree, qota info reads it without building anything; qota sample streams it by "
                      "blocks and qota shadow runs by tiles");
        }
      }
    }
    f.print(out, options.json);
    return 0;
  } catch (...) {
    return reportFailure("info", err);
  }
}

}  // namespace qota::tools
