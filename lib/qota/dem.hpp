// Terrains from elevation rasters, through GDAL: any raster GDAL reads (GeoTIFF, SRTM .hgt, USGS
// ASCII DEM, DTED, ...).
//
// Geometry: band 1 (or the band asked for), scaled by the band's scale and offset when it has
// them. One vertex at every pixel centre, at world position
//     x = gt[0] + (col + 0.5) gt[1] + (row + 0.5) gt[2]
//     y = gt[3] + (col + 0.5) gt[4] + (row + 0.5) gt[5]
//     z = value
// in the raster's CRS units (the full geotransform, rotated ones too). Each cell between four
// pixel centres is split into two triangles along the diagonal from its top-left centre (col,
// row) to its bottom-right centre (col + 1, row + 1): (TL, BL, BR) and (TL, BR, TR). The surface
// therefore spans the pixel centres; the outer half-cell border of the raster has no terrain.
//
// Nodata: a pixel equal to the band's nodata value, or NaN, has no vertex height; every triangle
// touching it is left out, so nodata makes holes.
//
// Frame: the Cartesian mapping with gravity -Z and its origin at the raster's centre (so UTM
// coordinates in the millions keep full precision in the index). The CRS (WKT) is kept with the
// terrain; coordinates are never reprojected here.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>

#include "qota/cartesian.hpp"
#include "qota/mesh.hpp"

namespace qota {

struct DemOptions {
  int band = 1;
  // Memory the terrain may use; 0 means the memory available on this machine. A raster that
  // would need more is refused before anything large is allocated.
  std::uint64_t memoryLimitBytes = 0;
};

struct DemTerrain {
  std::string path;
  std::string driver;  // GDAL driver short name
  int width = 0, height = 0;
  std::array<double, 6> geotransform{0, 1, 0, 0, 0, 1};
  std::string crsWkt;  // empty when the raster has no CRS
  std::optional<double> nodata;
  std::uint64_t nodataCells = 0;
  Mesh mesh;                   // vertex index = row * width + col
  CartesianMapping mapping;    // gravity -Z, origin at the raster centre

  // World (x, y) of the centre of pixel (col, row).
  std::array<double, 2> pixelCentre(double col, double row) const;
  // Fractional pixel coordinates (col, row) of a world point (col, row in [0, width] x [0, height]
  // on the raster).
  std::array<double, 2> pixelOf(double x, double y) const;
  // True when the world point lies on the raster's footprint.
  bool onRaster(double x, double y) const;
};

// Reads a raster into a terrain. Throws qota::Error naming the file when it cannot be opened, has
// no such band, or is too large for the memory limit.
DemTerrain loadDem(const std::string& path, const DemOptions& options = {});

// Memory available to this process for a new terrain, in bytes (MemAvailable, else physical).
std::uint64_t availableMemoryBytes();

// Registers GDAL's drivers once; safe to call from anywhere.
void ensureGdalRegistered();

}  // namespace qota
