// Points in a user's CRS carried to a raster's: the one conversion behind `--srs` (sample,
// viewshed), vector layers' own CRSs and Python's `srs=`. Both ends in GIS order (x is the
// longitude or the easting), as every qota input and GDAL's own tools take them.
#pragma once

#include <ogr_spatialref.h>

#include <memory>
#include <string>

namespace qota {

// `text` as GDAL's SetFromUserInput reads it (EPSG:4326, WKT, PROJ, a file); `name` names it in
// the error: "NAME 'TEXT' is not a coordinate reference system GDAL knows".
std::unique_ptr<OGRSpatialReference> crsFromUser(const std::string& text, const std::string& name);

// From `from` to the CRS `toWkt` (a raster's); throws `failure` when PROJ has no transformation.
std::unique_ptr<OGRCoordinateTransformation> transformTo(const OGRSpatialReference& from, const std::string& toWkt,
                                                         const std::string& failure);

}  // namespace qota
