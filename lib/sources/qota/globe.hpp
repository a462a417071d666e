// Terrains on curved worlds: a lon/lat raster closed into a planet (spherical mapping), a DEM on
// the WGS84 (or its own) ellipsoid (geodetic mapping), and the relief inside a rotating station
// (cylindrical mapping).
//
// Planet: the raster's pixel centres become vertices at radius R + height along their (lon, lat)
// direction; cells are split as in loadDem. When the raster spans 360 degrees of longitude, the
// cells between its last and first columns are added (the antimeridian is closed); when its
// first or last row of pixel centres is within one pixel of a pole, a vertex at the pole (height:
// the mean of that row) is fanned to the row (the caps are closed). A global raster without
// nodata is then a closed surface: every line from the centre meets it. Nodata pixels still make
// holes.
#pragma once

#include <cstdint>
#include <string>

#include "qota/dem.hpp"
#include "qota/geoid.hpp"
#include "qota/geodetic.hpp"
#include "qota/mesh.hpp"
#include "qota/spherical.hpp"
#include "qota/synthetic.hpp"

namespace qota {

struct PlanetOptions {
  DemOptions dem;
  // Reference radius R in metres. 0: the raster CRS's sphere radius, or the mean radius
  // (2a + b) / 3 of its ellipsoid (6,371,008.8 m for WGS84); a raster without a CRS is read as
  // lon/lat degrees on a sphere of Earth's mean radius.
  double radius = 0;
};

struct PlanetTerrain {
  DemTerrain dem;            // the raster's description; dem.mesh holds the planet's mesh
  SphericalMapping mapping;  // centred at the origin
  double radius = 0;         // the reference radius used
  bool wrapsLongitude = false, northCap = false, southCap = false;
};

// Reads a lon/lat raster as a planet. Throws qota::Error naming the file when it cannot be read,
// is not a north-up lon/lat grid, or its radius is not positive.
PlanetTerrain loadPlanet(const std::string& path, const PlanetOptions& options = {});

struct EllipsoidTerrain {
  DemTerrain dem;             // dem.mesh in geocentric (ECEF) metres
  GeodeticMapping mapping;    // the CRS's ellipsoid (WGS84 when it has none)
  HeightReference heightRef;  // what the raster's heights are over (DemOptions::heightRef)
};

// Reads a DEM in a geographic CRS (an SRTM tile, say) and puts every pixel centre at its height
// above the CRS's ellipsoid, with GeographicLib's geocentric conversion: the raster's height
// plus the geoid's undulation there when the heights are over a geoid (qota/geoid.hpp). Throws
// qota::Error when the raster is not in lon/lat degrees, or its geoid grid is missing or does
// not cover it.
EllipsoidTerrain loadOnEllipsoid(const std::string& path, const DemOptions& options = {});

// The ellipsoid (a, f) of a raster's CRS; WGS84 when it has none or it cannot be read.
void demEllipsoid(const DemTerrain& dem, double& a, double& f);
// True when the raster's CRS is geographic (or it has no CRS and lies within lon/lat bounds).
bool demIsLonLat(const DemTerrain& dem);
// The longitude/latitude CRS of the raster's own body, as gdalwarp -t_srs takes it ("EPSG:4326",
// "IAU_2015:49900", or a PROJ string in quotes); EPSG:4326 for a raster without CRS.
std::string geographicCrsOf(const DemTerrain& dem);

struct StationOptions {
  double radius = 250;   // distance from the spin axis to the zero level of the relief, metres
  double length = 1000;  // along the axis, centred on the axis point
};

// The inside of a rotating station: relief.nx columns around the axis (angle -180 + 360 i / nx,
// the last column joined to the first) by relief.ny rings along it, each vertex at distance
// radius - height from the axis (hills rise toward the axis); a NaN height is a hole (every
// triangle touching it is left out). Axis: the world z axis through the origin. Throws
// qota::Error unless radius > every height and the grid is at least 3 x 2.
Mesh stationMesh(const Heightfield& relief, const StationOptions& options);

}  // namespace qota
