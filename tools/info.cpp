// qota info: what a raster becomes as a terrain, and the statistics of its quadtree.
#include <GeographicLib/Geodesic.hpp>
#include <ogr_spatialref.h>

#include <chrono>
#include <cmath>
#include <iostream>

#include "qota/dem.hpp"
#include "qota/error.hpp"
#include "qota/mapping_registry.hpp"
#include "qota/treefile.hpp"
#include "qota_tools.hpp"
#include "text_output.hpp"

namespace qota::tools {
namespace {

void printCrs(const DemTerrain& dem, std::ostream& out) {
  if (dem.crsWkt.empty()) {
    out << "crs: none\n";
    return;
  }
  OGRSpatialReference srs;
  srs.importFromWkt(dem.crsWkt.c_str());
  if (!srs.GetAuthorityCode(nullptr)) srs.AutoIdentifyEPSG();  // e.g. an unnamed UTM zone
  const char* name = srs.GetName();
  const char* auth = srs.GetAuthorityName(nullptr);
  const char* code = srs.GetAuthorityCode(nullptr);
  out << "crs: " << (name ? name : "unnamed");
  if (auth && code) out << " (" << auth << ':' << code << ')';
  out << '\n';
  if (srs.IsGeographic()) {
    // Pixel size on the ground at the raster's centre, on the CRS's own ellipsoid.
    OGRErr e1 = OGRERR_NONE, e2 = OGRERR_NONE;
    const double a = srs.GetSemiMajor(&e1), invf = srs.GetInvFlattening(&e2);
    if (e1 != OGRERR_NONE || e2 != OGRERR_NONE) return;
    const GeographicLib::Geodesic geod(a, invf > 0 ? 1.0 / invf : 0.0);
    srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
    const double cc = (dem.width - 1) / 2.0, cr = (dem.height - 1) / 2.0;
    const auto p = dem.pixelCentre(cc, cr), px = dem.pixelCentre(cc + 1, cr), py = dem.pixelCentre(cc, cr + 1);
    double sx = 0, sy = 0;
    geod.Inverse(p[1], p[0], px[1], px[0], sx);
    geod.Inverse(p[1], p[0], py[1], py[0], sy);
    out << "pixel size on the ground (m): " << formatNumber(sx, 2) << " x " << formatNumber(sy, 2) << '\n';
  }
}

// The quadtree's statistics (the paper's Table 4 and the tree's shape) and memory.
void printTree(const QuadtreeStats& t, std::uint64_t memoryBytes, std::uint64_t triangles, std::ostream& out) {
  out << "nodes: " << t.nodes << '\n';
  out << "leaves: " << t.leaves << '\n';
  out << "empty leaves: " << t.emptyLeaves << '\n';
  out << "depth: " << t.depth << '\n';
  out << "leaf references: " << t.references << '\n';
  out << "max polygons per leaf: " << t.maxLeafItems << '\n';
  out << "mean polygons per leaf: " << formatNumber(t.meanLeafItems, 3) << '\n';
  out << "average tests per query: " << formatNumber(t.averageTests, 3) << '\n';
  out << "memory (bytes): " << memoryBytes << '\n';
  out << "memory (MB): " << formatNumber(static_cast<double>(memoryBytes) / 1e6, 3) << '\n';
  out << "bytes per triangle: "
      << formatNumber(triangles ? static_cast<double>(memoryBytes) / static_cast<double>(triangles) : 0.0, 1) << '\n';
}

// A tree file, a mesh, or a raster in a curved mapping: what it was built from, its mapping and
// its tree, and how long loading (or building) took.
int indexInfo(const InfoOptions& options, std::ostream& out) {
  const bool treeFile = isTreeFile(options.source.source);
  const auto start = std::chrono::steady_clock::now();
  const TreeFile tree = openIndex(options.source);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  out << "source: " << options.source.source << '\n';
  if (treeFile) {
    out << "driver: qota tree file\n";
    out << "built from: " << (tree.source.path.empty() ? std::string("unknown") : tree.source.path) << '\n';
  }
  if (tree.source.width > 0) out << "size: " << tree.source.width << " x " << tree.source.height << '\n';
  if (!tree.source.heightRef.empty()) out << "heights over: " << tree.source.heightRef << '\n';
  std::visit(
      [&](const auto& index) {
        out << "mapping: " << index.mapping().describe() << '\n';
        out << "polygons: " << index.stats().polygons << '\n';
        out << "triangles: " << index.stats().triangles << '\n';
        printTree(index.stats().tree, index.stats().memoryBytes, index.stats().triangles, out);
      },
      tree.index);
  out << (treeFile ? "load time (s): " : "build time (s): ") << formatNumber(seconds, 3) << '\n';
  return 0;
}

}  // namespace

int info(const InfoOptions& options, std::ostream& out, std::ostream& err) {
  try {
    const SourceOptions& so = options.source;
    requireSource(so.source);
    // A raster as a map: the raster's own description too. Anything else (a tree file, a mesh, a
    // raster in another mapping) as openIndex opens it for sample and build.
    if (isTreeFile(so.source) || !mappingEntry(so.mapping).map || !isRaster(so.source) || !so.heightRef.empty() ||
        so.origin || so.radius != 0 || so.length != 0) {
      return indexInfo(options, out);
    }
    // Statistics of the index in the raster's own x, y (degrees for a lon/lat raster): the
    // quadtree works in (u, v) whatever their unit.
    const DemTerrain dem = loadDem(so.source, {.band = so.band, .lonLatAsCartesian = true});
    const auto start = std::chrono::steady_clock::now();
    const CartesianIndex index(dem.mesh, dem.mapping, so.index);
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const IndexStats& s = index.stats();
    const QuadtreeStats& t = s.tree;

    out << "source: " << dem.path << '\n';
    out << "driver: " << dem.driver << '\n';
    out << "size: " << dem.width << " x " << dem.height << '\n';
    printCrs(dem, out);
    out << "geotransform:";
    for (double g : dem.geotransform) out << ' ' << formatNumber(g);
    out << '\n';
    out << "nodata: " << (dem.nodata ? formatNumber(*dem.nodata) : std::string("none")) << " (" << dem.nodataPixels
        << " pixels)\n";
    out << "mapping: " << index.mapping().describe() << '\n';
    out << "polygons: " << s.polygons << '\n';
    out << "triangles: " << s.triangles << '\n';
    out << "walls left out: " << s.leftOut << '\n';
    out << "max poly: " << so.index.tree.maxPoly << '\n';
    out << "max depth: " << so.index.tree.maxDepth << '\n';
    printTree(t, s.memoryBytes, s.triangles, out);
    out << "build time (s): " << formatNumber(seconds, 3) << '\n';
    return 0;
  } catch (...) {
    return reportFailure("info", err);
  }
}

}  // namespace qota::tools
