// qota info: what a raster becomes as a terrain, and the statistics of its quadtree.
#include <GeographicLib/Geodesic.hpp>
#include <ogr_spatialref.h>

#include <chrono>
#include <cmath>
#include <iostream>

#include "qota/dem.hpp"
#include "qota/error.hpp"
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
    // Cell size on the ground at the raster's centre, on the CRS's own ellipsoid.
    OGRErr e1 = OGRERR_NONE, e2 = OGRERR_NONE;
    const double a = srs.GetSemiMajor(&e1), invf = srs.GetInvFlattening(&e2);
    if (e1 != OGRERR_NONE || e2 != OGRERR_NONE) return;
    const GeographicLib::Geodesic geod(a, invf > 0 ? 1.0 / invf : 0.0);
    srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
    const double cc = (dem.width - 1) / 2.0, cr = (dem.height - 1) / 2.0;
    const auto p = dem.pixelCentre(cc, cr), px = dem.pixelCentre(cc + 1, cr),
               py = dem.pixelCentre(cc, cr + 1);
    double sx = 0, sy = 0;
    geod.Inverse(p[1], p[0], px[1], px[0], sx);
    geod.Inverse(p[1], p[0], py[1], py[0], sy);
    out << "pixel size on the ground (m): " << formatNumber(sx, 2) << " x " << formatNumber(sy, 2)
        << '\n';
  }
}

}  // namespace

int info(const InfoOptions& options, std::ostream& out, std::ostream& err) {
  try {
    const DemTerrain dem = loadDem(options.source);
    const auto start = std::chrono::steady_clock::now();
    const TerrainIndex index(dem.mesh, dem.mapping, options.terrain);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const TerrainStats& s = index.stats();
    const QuadtreeStats& t = s.tree;

    out << "source: " << dem.path << '\n';
    out << "driver: " << dem.driver << '\n';
    out << "size: " << dem.width << " x " << dem.height << '\n';
    printCrs(dem, out);
    out << "geotransform:";
    for (double g : dem.geotransform) out << ' ' << formatNumber(g);
    out << '\n';
    out << "nodata: " << (dem.nodata ? formatNumber(*dem.nodata) : std::string("none")) << " ("
        << dem.nodataCells << " cells)\n";
    out << "mapping: " << index.mapping().describe() << '\n';
    out << "polygons: " << s.polygons << '\n';
    out << "triangles: " << s.triangles << '\n';
    out << "walls left out: " << s.walls << '\n';
    out << "max poly: " << options.terrain.tree.maxPoly << '\n';
    out << "max depth: " << options.terrain.tree.maxDepth << '\n';
    out << "nodes: " << t.nodes << '\n';
    out << "leaves: " << t.leaves << '\n';
    out << "empty leaves: " << t.emptyLeaves << '\n';
    out << "depth: " << t.depth << '\n';
    out << "leaf references: " << t.references << '\n';
    out << "max polygons per leaf: " << t.maxLeafItems << '\n';
    out << "mean polygons per leaf: " << formatNumber(t.meanLeafItems, 3) << '\n';
    out << "average tests per query: " << formatNumber(t.averageTests, 3) << '\n';
    out << "memory (bytes): " << s.memoryBytes << '\n';
    out << "memory (MB): " << formatNumber(static_cast<double>(s.memoryBytes) / 1e6, 3) << '\n';
    out << "bytes per triangle: "
        << formatNumber(s.triangles ? static_cast<double>(s.memoryBytes) / static_cast<double>(s.triangles) : 0.0, 1)
        << '\n';
    out << "build time (s): " << formatNumber(seconds, 3) << '\n';
    return 0;
  } catch (const Error& e) {
    err << "qota info: " << e.what() << '\n';
    return 2;
  }
}

}  // namespace qota::tools
