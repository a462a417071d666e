#include "qota/shadow.hpp"

#include <Eigen/Geometry>
#include <GeographicLib/LocalCartesian.hpp>
#include <ogr_spatialref.h>

#include <atomic>
#include <cmath>
#include <memory>
#include <thread>

#include "qota/error.hpp"
#include "qota/globe.hpp"
#include "qota/predicates.hpp"

namespace qota {
namespace {

constexpr double kDeg = M_PI / 180.0;

// A raster's axes are x = easting or longitude, y = northing or latitude (GDAL's convention for
// rasters), whatever the CRS's official axis order.
OGRSpatialReference rasterCrs(const DemTerrain& dem) {
  OGRSpatialReference srs;
  if (srs.importFromWkt(dem.crsWkt.c_str()) != OGRERR_NONE) {
    throw Error(dem.path + ": its coordinate reference system cannot be read");
  }
  srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  return srs;
}

// Fills NaN heights from their neighbours, rim inwards (onion peeling, as gdal_fillnodata does in
// spirit): each pass gives every void cell next to known cells the mean of those, until none is
// left. A raster with no data at all becomes flat at 0.
void fillVoids(std::vector<double>& z, int w, int h) {
  std::vector<std::size_t> todo;
  for (std::size_t i = 0; i < z.size(); ++i) {
    if (!std::isfinite(z[i])) todo.push_back(i);
  }
  std::vector<std::pair<std::size_t, double>> fills;
  while (!todo.empty()) {
    fills.clear();
    std::vector<std::size_t> still;
    for (std::size_t i : todo) {
      const int c = static_cast<int>(i % w), r = static_cast<int>(i / w);
      double sum = 0;
      int count = 0;
      for (int dr = -1; dr <= 1; ++dr) {
        for (int dc = -1; dc <= 1; ++dc) {
          const int cc = c + dc, rr = r + dr;
          if ((dr || dc) && cc >= 0 && rr >= 0 && cc < w && rr < h) {
            const double v = z[static_cast<std::size_t>(rr) * w + cc];
            if (std::isfinite(v)) sum += v, ++count;
          }
        }
      }
      if (count) {
        fills.push_back({i, sum / count});
      } else {
        still.push_back(i);
      }
    }
    if (fills.empty()) {  // nothing known anywhere
      for (std::size_t i : still) z[i] = 0;
      break;
    }
    for (const auto& [i, v] : fills) z[i] = v;
    todo.swap(still);
  }
}

}  // namespace

Eigen::Vector3d LocalFrame::towardSun(const SunPosition& sun) const {
  SunPosition inFrame = sun;
  inFrame.azimuth = sun.azimuth + trueNorthFromY;
  return towardSunEnu(inFrame);
}

LocalFrame localFrame(const DemTerrain& dem, bool flat, double pixelSize) {
  LocalFrame f;
  f.width = dem.width;
  f.height = dem.height;
  const std::size_t n = dem.mesh.vertices.size();
  // Heights with the voids filled (for occlusion only), and which cells have data.
  std::vector<double> z(n);
  f.valid.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    z[i] = dem.mesh.vertices[i].z();
    f.valid[i] = std::isfinite(z[i]);
  }
  fillVoids(z, dem.width, dem.height);
  // Every cell's two triangles, split as the DEM's (top-left to bottom-right diagonal).
  for (int r = 0; r + 1 < dem.height; ++r) {
    for (int c = 0; c + 1 < dem.width; ++c) {
      const auto tl = static_cast<std::uint32_t>(r * dem.width + c), tr = tl + 1;
      const auto bl = static_cast<std::uint32_t>(tl + dem.width), br = bl + 1;
      f.mesh.addTriangle(tl, bl, br);
      f.mesh.addTriangle(tl, br, tr);
    }
  }
  f.mesh.vertices.resize(n);
  const double cc = (dem.width - 1) / 2.0, cr = (dem.height - 1) / 2.0;
  const auto centre = dem.pixelCentre(cc, cr);

  if (dem.crsWkt.empty()) {
    if (!(pixelSize > 0)) {
      throw Error(dem.path + ": the raster has no coordinate reference system, so the size of its "
                  "pixels in metres is unknown; give it with --pixel-size METRES");
    }
    // Pixel grid, rows running south.
    for (std::size_t i = 0; i < n; ++i) {
      const double c = static_cast<double>(i % dem.width), r = static_cast<double>(i / dem.width);
      f.mesh.vertices[i] = {(c - cc) * pixelSize, -(r - cr) * pixelSize, z[i]};
    }
    f.description = "pixel grid, " + std::to_string(pixelSize) + " m per pixel (no CRS)";
  } else {
    const OGRSpatialReference srs = rasterCrs(dem);
    if (srs.IsGeographic()) {
      double a = 0, fl = 0;
      demEllipsoid(dem, a, fl);
      const double lon0 = centre[0], lat0 = centre[1];
      f.geographicLocation = true;
      f.centreLon = lon0;
      f.centreLat = lat0;
      if (flat) {
        // Longitude and latitude scaled linearly by the ellipsoid's radii of curvature at the
        // centre: no curvature.
        const double e2 = fl * (2 - fl), s = std::sin(lat0 * kDeg);
        const double w = std::sqrt(1 - e2 * s * s);
        const double nRad = a / w, mRad = a * (1 - e2) / (w * w * w);
        for (std::size_t i = 0; i < n; ++i) {
          const Eigen::Vector3d& p = dem.mesh.vertices[i];
          f.mesh.vertices[i] = {(p.x() - lon0) * kDeg * nRad * std::cos(lat0 * kDeg),
                                (p.y() - lat0) * kDeg * mRad, z[i]};
        }
        f.description = "flat east-north-up metres around the centre (--flat)";
      } else {
        const GeographicLib::LocalCartesian local(lat0, lon0, 0, GeographicLib::Geocentric(a, fl));
        for (std::size_t i = 0; i < n; ++i) {
          const Eigen::Vector3d& p = dem.mesh.vertices[i];
          Eigen::Vector3d& q = f.mesh.vertices[i];
          local.Forward(p.y(), p.x(), z[i], q.x(), q.y(), q.z());
        }
        f.description = "east-north-up metres on the ellipsoid (a = " + std::to_string(a) +
                        " m), tangent at the centre";
      }
    } else {
      const double unit = srs.GetLinearUnits();
      for (std::size_t i = 0; i < n; ++i) {
        const Eigen::Vector3d& p = dem.mesh.vertices[i];
        f.mesh.vertices[i] = {(p.x() - centre[0]) * unit, (p.y() - centre[1]) * unit, z[i]};
      }
      f.description = "projected grid metres";
      // Where the centre is, and where true north points on the grid there.
      OGRSpatialReference geo;
      geo.CopyGeogCSFrom(&srs);
      geo.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
      std::unique_ptr<OGRCoordinateTransformation> toGeo(OGRCreateCoordinateTransformation(&srs, &geo));
      std::unique_ptr<OGRCoordinateTransformation> toGrid(OGRCreateCoordinateTransformation(&geo, &srs));
      double x = centre[0], y = centre[1];
      if (toGeo && toGrid && toGeo->Transform(1, &x, &y)) {
        f.geographicLocation = true;
        f.centreLon = x;
        f.centreLat = y;
        double nx = x, ny = y + 0.01;
        if (toGrid->Transform(1, &nx, &ny)) {
          f.trueNorthFromY = std::atan2(nx - centre[0], ny - centre[1]) / kDeg;
        }
      }
    }
  }
  f.minHeight = INFINITY;
  f.maxHeight = -INFINITY;
  for (std::size_t i = 0; i < n; ++i) {
    if (f.valid[i]) {
      f.minHeight = std::min(f.minHeight, f.mesh.vertices[i].z());
      f.maxHeight = std::max(f.maxHeight, f.mesh.vertices[i].z());
    }
  }
  if (!(f.minHeight <= f.maxHeight)) f.minHeight = f.maxHeight = 0;
  if (dem.width > 1 && dem.height > 1) {
    // Every vertex has a position (voids are filled), so the centre's neighbours give the size.
    const std::size_t ci = static_cast<std::size_t>(std::floor(cr)) * dem.width +
                           static_cast<std::size_t>(std::floor(cc));
    const auto& v = f.mesh.vertices;
    f.pixelSizeX = (v[ci + 1] - v[ci]).head<2>().norm();
    f.pixelSizeY = (v[ci + dem.width] - v[ci]).head<2>().norm();
  }

  return f;
}

namespace {

// Triangles around each vertex, as offsets into one list (a vertex of a DEM has at most 6).
struct VertexStar {
  std::vector<std::uint32_t> start, tris;
  VertexStar(const Mesh& mesh) : start(mesh.vertices.size() + 1, 0) {
    for (std::uint32_t idx : mesh.indices) ++start[idx + 1];
    for (std::size_t i = 1; i < start.size(); ++i) start[i] += start[i - 1];
    tris.resize(mesh.indices.size());
    std::vector<std::uint32_t> fill(start.begin(), start.end() - 1);
    for (std::size_t t = 0; t < mesh.polygonCount(); ++t) {
      for (std::uint32_t idx : mesh.polygon(t)) tris[fill[idx]++] = static_cast<std::uint32_t>(t);
    }
  }
};

// Attached shadow: the light arrives from below the surface at vertex i. Seen from above (the
// frame's z), the light's horizontal direction leaves i through one of its own triangles (exactly:
// the one whose corner sector at i contains that direction); the vertex is in attached shadow when
// the light rises more slowly than that triangle does in that direction. A light straight up, or
// a direction leaving the terrain (across a void or the border), is not attached shadow.
bool attachedShadow(const Mesh& mesh, const VertexStar& star, std::uint32_t i, const Eigen::Vector3d& light) {
  const Eigen::Vector3d& p = mesh.vertices[i];
  const Point2 p2{p.x(), p.y()}, s2{p.x() + light.x(), p.y() + light.y()};
  if (light.x() == 0 && light.y() == 0) return false;
  for (std::uint32_t k = star.start[i]; k < star.start[i + 1]; ++k) {
    const auto t = mesh.polygon(star.tris[k]);
    // The other two corners, in counter-clockwise order around i.
    std::uint32_t a = t[0] == i ? t[1] : t[1] == i ? t[2] : t[0];
    std::uint32_t b = t[0] == i ? t[2] : t[1] == i ? t[0] : t[1];
    Point2 a2{mesh.vertices[a].x(), mesh.vertices[a].y()}, b2{mesh.vertices[b].x(), mesh.vertices[b].y()};
    const int orientation = orient2dSign(p2, a2, b2);
    if (orientation == 0) continue;
    if (orientation < 0) std::swap(a, b), std::swap(a2, b2);
    if (orient2dSign(p2, a2, s2) < 0 || orient2dSign(p2, s2, b2) < 0) continue;  // not this sector
    // The triangle's rise along the light's horizontal direction, against the light's own rise.
    const Eigen::Vector3d n = (mesh.vertices[a] - p).cross(mesh.vertices[b] - p);  // up-facing
    // On the plane, dz = -(n.x dx + n.y dy) / n.z; below it when light.z < dz.
    return light.z() * n.z() < -(n.x() * light.x() + n.y() * light.y());
  }
  return false;
}

}  // namespace

double shadowReach(const LocalFrame& frame, const Eigen::Vector3d& towardLight) {
  const Eigen::Vector3d d = towardLight.normalized();
  const double horizontal = d.head<2>().norm();
  if (d.z() <= 0) return INFINITY;
  return (frame.maxHeight - frame.minHeight) * horizontal / d.z();
}

std::vector<Light> shadowMask(const LocalFrame& frame, const Eigen::Vector3d& towardLight,
                              const TerrainOptions& options, const Progress& progress,
                              unsigned threadCount) {
  const auto& vertices = frame.mesh.vertices;
  const std::size_t n = vertices.size();
  std::vector<Light> out(n, Light::NoData);
  const auto report = [&](double done, const char* message) {
    if (progress && !progress(done, message)) throw Error("shadow computation cancelled");
  };
  if (!towardLight.allFinite() || towardLight.squaredNorm() == 0) {
    throw Error("light direction must be a nonzero finite vector");
  }
  const Eigen::Vector3d light = towardLight.normalized();
  if (light.z() <= 0) {
    // The light is at or below the horizon: no direct light anywhere.
    for (std::size_t i = 0; i < n; ++i) {
      if (frame.valid[i]) out[i] = Light::Shadow;
    }
    report(1.0, "light below the horizon");
    return out;
  }

  report(0.0, "building the shadow quadtree");
  // Only triangles facing away from the light can cast a shadow on a cell that is not in attached
  // shadow: its ray starts into the open air, so the first terrain it meets, it enters, and it
  // enters through a triangle whose normal points away from the light. The quadtree therefore
  // holds those alone (and, to stay on the safe side of rounding, those within 1e-9 of edge-on):
  // the same answers as with every triangle, for a fraction of the build.
  Mesh occluders;
  occluders.vertices = frame.mesh.vertices;
  for (std::size_t t = 0; t < frame.mesh.polygonCount(); ++t) {
    const auto c = frame.mesh.polygon(t);
    const Eigen::Vector3d& a = frame.mesh.vertices[c[0]];
    const Eigen::Vector3d n = (frame.mesh.vertices[c[1]] - a).cross(frame.mesh.vertices[c[2]] - a);
    // Up-facing normal in the frame (z up); the DEM's corner order may be either way round.
    const Eigen::Vector3d up = n.z() >= 0 ? n : Eigen::Vector3d(-n);
    if (up.dot(light) <= 1e-9 * up.norm()) occluders.addTriangle(c[0], c[1], c[2]);
  }
  // The light's direction of travel is the "gravity" of the shadow quadtree: "above" a point
  // means toward the light.
  const TerrainIndex index(occluders, CartesianMapping(-light), options);
  const CartesianMapping& mapping = index.mapping();
  const VertexStar star(frame.mesh);
  report(0.3, "testing cells");

  // Rows are shared out to the machine's cores; the calling thread reports progress.
  const auto rows = static_cast<std::size_t>(frame.height);
  const auto width = static_cast<std::size_t>(frame.width);
  std::atomic<std::size_t> nextRow{0}, rowsDone{0};
  std::atomic<bool> stop{false};
  const auto work = [&](bool reporter) {
    for (std::size_t r; !stop && (r = nextRow++) < rows;) {
      for (std::size_t c = 0; c < width; ++c) {
        const std::size_t i = r * width + c;
        if (!frame.valid[i]) continue;
        const auto vi = static_cast<std::uint32_t>(i);
        const Eigen::Vector3d m = mapping.toMapped(vertices[i]);
        const bool shadowed = attachedShadow(frame.mesh, star, vi, light) ||
                              index.occludedAbove(m.x(), m.y(), m.z(), vi);
        out[i] = shadowed ? Light::Shadow : Light::Lit;
      }
      const std::size_t done = ++rowsDone;
      if (reporter && progress && !progress(0.3 + 0.7 * static_cast<double>(done) / rows, "testing cells")) {
        stop = true;
      }
    }
  };
  const unsigned threads =
      threadCount ? threadCount : std::max(1u, std::min(8u, std::thread::hardware_concurrency()));
  std::vector<std::thread> pool;
  for (unsigned t = 1; t < threads; ++t) pool.emplace_back(work, false);
  work(true);
  for (auto& t : pool) t.join();
  if (stop) throw Error("shadow computation cancelled");
  report(1.0, "done");
  return out;
}

}  // namespace qota
