#include "qota/dem.hpp"

#include <cpl_error.h>
#include <gdal_priv.h>
#include <ogr_spatialref.h>
#include <unistd.h>

#include <cmath>
#include <fstream>
#include <memory>
#include <mutex>
#include <sstream>
#include <vector>

#include "gdal_errors.hpp"
#include "qota/error.hpp"
#include "qota/terrain.hpp"

namespace qota {
namespace {

using detail::QuietGdalErrors;
using detail::gdalMessage;

std::string gib(std::uint64_t bytes) {
  std::ostringstream s;
  s.precision(3);
  s << static_cast<double>(bytes) / (1024.0 * 1024.0 * 1024.0) << " GiB";
  return s.str();
}

}  // namespace

void ensureGdalRegistered() {
  static std::once_flag once;
  std::call_once(once, [] { GDALAllRegister(); });
}

std::uint64_t availableMemoryBytes() {
  std::ifstream meminfo("/proc/meminfo");
  std::string key;
  std::uint64_t kib = 0;
  std::string unit;
  while (meminfo >> key >> kib >> unit) {
    if (key == "MemAvailable:") return kib * 1024;
  }
  const long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGE_SIZE);
  return pages > 0 && page > 0 ? static_cast<std::uint64_t>(pages) * static_cast<std::uint64_t>(page)
                               : 0;
}

std::array<double, 2> DemTerrain::pixelCentre(double col, double row) const {
  const auto& g = geotransform;
  return {g[0] + (col + 0.5) * g[1] + (row + 0.5) * g[2],
          g[3] + (col + 0.5) * g[4] + (row + 0.5) * g[5]};
}

std::array<double, 2> DemTerrain::pixelOf(double x, double y) const {
  double inv[6];
  double gt[6];
  std::copy(geotransform.begin(), geotransform.end(), gt);
  if (!GDALInvGeoTransform(gt, inv)) return {NAN, NAN};
  return {inv[0] + x * inv[1] + y * inv[2], inv[3] + x * inv[4] + y * inv[5]};
}

bool DemTerrain::onRaster(double x, double y) const {
  const auto [col, row] = pixelOf(x, y);
  return col >= 0 && col <= width && row >= 0 && row <= height;
}

DemTerrain loadDem(const std::string& path, const DemOptions& options) {
  ensureGdalRegistered();
  QuietGdalErrors quiet;
  std::unique_ptr<GDALDataset> ds(
      GDALDataset::Open(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY | GDAL_OF_VERBOSE_ERROR));
  if (!ds) throw Error(path + ": cannot open as a raster" + gdalMessage());
  if (options.band < 1 || options.band > ds->GetRasterCount()) {
    throw Error(path + ": has " + std::to_string(ds->GetRasterCount()) + " band(s), no band " +
                std::to_string(options.band));
  }
  GDALRasterBand* band = ds->GetRasterBand(options.band);

  DemTerrain dem;
  dem.path = path;
  dem.driver = ds->GetDriver() ? ds->GetDriver()->GetDescription() : "";
  dem.width = ds->GetRasterXSize();
  dem.height = ds->GetRasterYSize();
  double gt[6];
  if (ds->GetGeoTransform(gt) == CE_None) std::copy(gt, gt + 6, dem.geotransform.begin());
  if (const OGRSpatialReference* srs = ds->GetSpatialRef()) {
    char* wkt = nullptr;
    if (srs->exportToWkt(&wkt) == OGRERR_NONE && wkt) dem.crsWkt = wkt;
    CPLFree(wkt);
  }
  int hasNodata = 0;
  const double nodata = band->GetNoDataValue(&hasNodata);
  if (hasNodata) dem.nodata = nodata;

  // Refuse what cannot fit before allocating: the raster as doubles, the mesh, and the index.
  const std::uint64_t w = static_cast<std::uint64_t>(dem.width);
  const std::uint64_t h = static_cast<std::uint64_t>(dem.height);
  const std::uint64_t vertices = w * h;
  const std::uint64_t triangles = w > 1 && h > 1 ? 2 * (w - 1) * (h - 1) : 0;
  const std::uint64_t need = vertices * (sizeof(double) + sizeof(Eigen::Vector3d)) +
                             triangles * 3 * sizeof(std::uint32_t) +
                             TerrainIndex::estimateBuildBytes(vertices, triangles);
  const std::uint64_t limit =
      options.memoryLimitBytes ? options.memoryLimitBytes : availableMemoryBytes();
  if (vertices >= 0xffffffffull || (limit && need > limit)) {
    throw Error(path + ": a " + std::to_string(dem.width) + " x " + std::to_string(dem.height) +
                " raster needs about " + gib(need) + " to build its terrain, more than the " +
                gib(limit) + " of memory available; cut it into tiles (gdal_translate -srcwin) "
                "or resample it");
  }

  std::vector<double> z(vertices);
  if (vertices && band->RasterIO(GF_Read, 0, 0, dem.width, dem.height, z.data(), dem.width,
                                 dem.height, GDT_Float64, 0, 0) != CE_None) {
    throw Error(path + ": cannot read band " + std::to_string(options.band) + gdalMessage());
  }
  int hasScale = 0, hasOffset = 0;
  const double scale = band->GetScale(&hasScale), offset = band->GetOffset(&hasOffset);
  const bool rescale = (hasScale && scale != 1.0) || (hasOffset && offset != 0.0);

  // Vertices: every pixel centre; a nodata pixel gets NaN height and no triangle uses it.
  std::vector<std::uint8_t> valid(vertices);
  dem.mesh.vertices.resize(vertices);
  for (std::uint64_t r = 0; r < h; ++r) {
    for (std::uint64_t c = 0; c < w; ++c) {
      const std::uint64_t i = r * w + c;
      double value = z[i];
      const bool ok = std::isfinite(value) && !(hasNodata && value == nodata);
      if (!ok) {
        ++dem.nodataCells;
        value = NAN;
      } else if (rescale) {
        value = value * (hasScale ? scale : 1.0) + (hasOffset ? offset : 0.0);
      }
      valid[i] = ok;
      const auto xy = dem.pixelCentre(static_cast<double>(c), static_cast<double>(r));
      dem.mesh.vertices[i] = Eigen::Vector3d(xy[0], xy[1], value);
    }
  }
  std::vector<double>().swap(z);

  // Two triangles per cell, split along the top-left to bottom-right diagonal.
  dem.mesh.indices.reserve(triangles * 3);
  for (std::uint64_t r = 0; r + 1 < h; ++r) {
    for (std::uint64_t c = 0; c + 1 < w; ++c) {
      const auto tl = static_cast<std::uint32_t>(r * w + c), tr = tl + 1;
      const auto bl = static_cast<std::uint32_t>(tl + w), br = bl + 1;
      if (valid[tl] && valid[bl] && valid[br]) dem.mesh.addTriangle(tl, bl, br);
      if (valid[tl] && valid[br] && valid[tr]) dem.mesh.addTriangle(tl, br, tr);
    }
  }

  const auto centre = dem.pixelCentre((dem.width - 1) / 2.0, (dem.height - 1) / 2.0);
  dem.mapping = CartesianMapping(Eigen::Vector3d(0, 0, -1), Eigen::Vector3d(centre[0], centre[1], 0));
  return dem;
}

}  // namespace qota
