#include "qota/globe.hpp"

#include <GeographicLib/Constants.hpp>
#include <GeographicLib/Math.hpp>
#include <cmath>
#include <gdal_priv.h>
#include <ogr_spatialref.h>

#include "qota/error.hpp"
#include "qota/raster_grid.hpp"

namespace qota {
namespace {

bool readCrs(const DemTerrain& dem, OGRSpatialReference& srs) {
  if (dem.crsWkt.empty() || srs.importFromWkt(dem.crsWkt.c_str()) != OGRERR_NONE) return false;
  srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  return true;
}

}  // namespace

std::string geographicCrsOf(const DemTerrain& dem) {
  OGRSpatialReference srs;
  if (!readCrs(dem, srs)) return "EPSG:4326";
  OGRSpatialReference geo;
  if (geo.CopyGeogCSFrom(&srs) != OGRERR_NONE) return "EPSG:4326";
  const char* authority = geo.GetAuthorityName(nullptr);
  const char* code = geo.GetAuthorityCode(nullptr);
  if (authority && code) return std::string(authority) + ":" + code;
  // No identifier (a body's CRS written without one): its PROJ string, which gdalwarp takes.
  char* proj4 = nullptr;
  std::string out = "EPSG:4326";
  if (geo.exportToProj4(&proj4) == OGRERR_NONE && proj4 && *proj4) {
    out = std::string("'") + proj4 + "'";
    while (out.size() > 2 && out[out.size() - 2] == ' ') out.erase(out.size() - 2, 1);
  }
  CPLFree(proj4);
  return out;
}

namespace {

// Checks that the raster is a north-up lon/lat grid (the only layout a globe is built from).
void requireLonLatGrid(const DemTerrain& dem, const char* what) {
  const auto& gt = dem.geotransform;
  if (!demIsLonLat(dem)) {
    throw Error(dem.path + ": " + what +
                " needs a raster in longitude/latitude degrees (a "
                "geographic CRS); reproject it with gdalwarp -t_srs " +
                geographicCrsOf(dem) + " (its own body's longitude/latitude)");
  }
  if (gt[2] != 0.0 || gt[4] != 0.0 || !(gt[1] > 0.0) || !(gt[5] < 0.0)) {
    throw Error(dem.path + ": " + what +
                " needs a north-up raster without rotation "
                "(geotransform with positive pixel width and negative pixel height)");
  }
}

}  // namespace

void demEllipsoid(const DemTerrain& dem, double& a, double& f) {
  a = GeographicLib::Constants::WGS84_a();
  f = GeographicLib::Constants::WGS84_f();
  OGRSpatialReference srs;
  if (!readCrs(dem, srs)) return;
  OGRErr e1 = OGRERR_NONE, e2 = OGRERR_NONE;
  const double sa = srs.GetSemiMajor(&e1);
  const double invf = srs.GetInvFlattening(&e2);
  if (e1 == OGRERR_NONE && e2 == OGRERR_NONE && sa > 0) {
    a = sa;
    f = invf > 0 ? 1.0 / invf : 0.0;
  }
}

bool demIsLonLat(const DemTerrain& dem) {
  OGRSpatialReference srs;
  if (readCrs(dem, srs)) return srs.IsGeographic();
  // No CRS: accept a grid that lies within the lon/lat ranges.
  const auto lo = dem.pixelCentre(0, 0);
  const auto hi = dem.pixelCentre(dem.width - 1, dem.height - 1);
  for (const auto& p : {lo, hi}) {
    if (!(p[0] >= -360.0 && p[0] <= 360.0 && p[1] >= -90.0 && p[1] <= 90.0)) return false;
  }
  return true;
}

PlanetTerrain loadPlanet(const std::string& path, const PlanetOptions& options) {
  PlanetTerrain planet;
  DemOptions demOptions = options.dem;
  demOptions.lonLatAsCartesian = true;  // read as lon/lat, placed on the sphere below
  planet.dem = loadDem(path, demOptions);
  DemTerrain& dem = planet.dem;
  requireLonLatGrid(dem, "a planet");
  double radius = options.radius;
  if (radius == 0) {
    double a, f;
    demEllipsoid(dem, a, f);
    radius = f == 0 ? a : (2.0 * a + a * (1.0 - f)) / 3.0;  // IUGG mean radius R1
  }
  if (!(radius > 0) || !std::isfinite(radius)) {
    throw Error(path + ": planet radius must be positive, got " + std::to_string(radius));
  }
  planet.radius = radius;

  const auto& gt = dem.geotransform;
  const int w = dem.width, h = dem.height;
  Mesh& mesh = dem.mesh;
  auto valid = [&](std::uint32_t i) { return std::isfinite(mesh.vertices[i].z()); };
  // The mean height of a row's cells (NaN: none has one), the pole's height when a cap closes it.
  const auto rowMean = [&](int row) {
    double sum = 0;
    int n = 0;
    for (int c = 0; c < w; ++c) {
      const double z = mesh.vertices[static_cast<std::size_t>(row) * w + c].z();
      if (std::isfinite(z)) sum += z, ++n;
    }
    return n ? sum / n : NAN;
  };
  // The closure of the grid (raster_grid.hpp): the antimeridian's cells between the last column
  // and the first, and a vertex at a pole fanned to the first (last) row when that row is within
  // a pixel of the pole and has heights.
  RasterGrid::Closure closure;
  closure.wrapsColumns = std::fabs(w * gt[1] - 360.0) < 0.5 * gt[1];
  const double pixel = -gt[5];
  if (closure.wrapsColumns) {
    const double top = dem.pixelCentre(0, 0)[1], bottom = dem.pixelCentre(0, h - 1)[1];
    closure.northCap = 90.0 - top <= pixel && top < 90.0 && std::isfinite(rowMean(0));
    closure.southCap = bottom + 90.0 <= pixel && bottom > -90.0 && std::isfinite(rowMean(h - 1));
  }
  const RasterGrid grid(w, h, closure);
  planet.wrapsLongitude = grid.closure().wrapsColumns;
  planet.northCap = grid.closure().northCap;
  planet.southCap = grid.closure().southCap;
  for (const RasterGrid::ExtraVertex& e : grid.extraVertices()) {
    mesh.addVertex({0.0, 90.0 * e.pole, rowMean(e.pole > 0 ? 0 : h - 1)});
  }
  // loadDem made the inner triangles; the closure's follow them.
  grid.appendTriangles(mesh, valid, grid.innerTriangleCount());
  // Lon/lat/height to the sphere, heights in metres.
  const double metres = dem.verticalUnit.metresPerUnit;
  for (Eigen::Vector3d& p : mesh.vertices) {
    if (!std::isfinite(p.z())) continue;
    p = (radius + p.z() * metres) * SphericalMapping::up(p.x(), p.y());
  }
  return planet;
}

EllipsoidTerrain loadOnEllipsoid(const std::string& path, const DemOptions& options) {
  DemOptions demOptions = options;
  demOptions.lonLatAsCartesian = true;  // read as lon/lat, placed on the ellipsoid below
  DemTerrain dem = loadDem(path, demOptions);
  if (!demIsLonLat(dem)) {
    throw Error(dem.path +
                ": the geodetic mapping needs a raster in longitude/latitude degrees "
                "(a geographic CRS); reproject it with gdalwarp -t_srs " +
                geographicCrsOf(dem) + " (its own body's longitude/latitude)");
  }
  double a, f;
  demEllipsoid(dem, a, f);
  HeightReference reference = heightReferenceOf(dem, options.heightRef);
  EllipsoidTerrain terrain{std::move(dem), GeodeticMapping(a, f), std::move(reference)};
  const Geoid geoid(terrain.heightRef);
  const double metres = terrain.dem.verticalUnit.metresPerUnit;
  for (Eigen::Vector3d& p : terrain.dem.mesh.vertices) {
    if (!std::isfinite(p.z())) continue;
    // (lon, lat, h) is the mapped point, h in metres over the ellipsoid: over the geoid, plus its
    // undulation there.
    const double n = geoid.undulation(p.x(), p.y());
    if (std::isnan(n)) {
      throw Error(terrain.dem.path + ": the point " + std::to_string(p.x()) + ", " + std::to_string(p.y()) +
                  " is outside the geoid grid " + terrain.heightRef.grid);
    }
    p = terrain.mapping.toWorld(Eigen::Vector3d(p.x(), p.y(), p.z() * metres + n));
  }
  return terrain;
}

Mesh stationMesh(const Heightfield& relief, const StationOptions& options) {
  const int nx = relief.nx, ny = relief.ny;
  if (nx < 3 || ny < 2 || relief.z.size() != static_cast<std::size_t>(nx) * ny) {
    throw Error("station: the relief grid must be at least 3 x 2, got " + std::to_string(nx) + " x " +
                std::to_string(ny));
  }
  if (!(options.radius > 0) || !(options.length > 0)) {
    throw Error("station: radius and length must be positive");
  }
  Mesh mesh;
  mesh.vertices.reserve(static_cast<std::size_t>(nx) * ny);
  for (int j = 0; j < ny; ++j) {
    const double axial = -0.5 * options.length + options.length * j / (ny - 1);
    for (int i = 0; i < nx; ++i) {
      const double r = options.radius - relief.at(i, j);
      if (std::isnan(r)) {  // nodata: a hole (a window in the hull)
        mesh.addVertex({NAN, NAN, NAN});
        continue;
      }
      if (!(r > 0) || !std::isfinite(r)) {
        throw Error("station: relief height " + std::to_string(relief.at(i, j)) + " at (" + std::to_string(i) + ", " +
                    std::to_string(j) + ") reaches the axis (radius " + std::to_string(options.radius) + ")");
      }
      double s, c;
      GeographicLib::Math::sincosd(-180.0 + 360.0 * i / nx, s, c);
      mesh.addVertex({r * c, r * s, axial});
    }
  }
  // Rows along the axis, columns round it: the grid's rule with the seam closed (raster_grid.hpp);
  // a window (nodata) makes a hole.
  RasterGrid(nx, ny, {.wrapsColumns = true}).appendTriangles(mesh, [&](std::uint32_t k) {
    return std::isfinite(mesh.vertices[k].x());
  });
  return mesh;
}

}  // namespace qota
