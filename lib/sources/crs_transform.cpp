#include "qota/crs_transform.hpp"

#include "qota/error.hpp"

namespace qota {

std::unique_ptr<OGRSpatialReference> crsFromUser(const std::string& text, const std::string& name) {
  auto crs = std::make_unique<OGRSpatialReference>();
  if (crs->SetFromUserInput(text.c_str()) != OGRERR_NONE) {
    throw Error(name + " '" + text + "' is not a coordinate reference system GDAL knows");
  }
  return crs;
}

std::unique_ptr<OGRCoordinateTransformation> transformTo(const OGRSpatialReference& from, const std::string& toWkt,
                                                         const std::string& failure) {
  OGRSpatialReference source(from), to;
  to.importFromWkt(toWkt.c_str());
  source.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  to.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  std::unique_ptr<OGRCoordinateTransformation> ct(OGRCreateCoordinateTransformation(&source, &to));
  if (!ct) throw Error(failure);
  return ct;
}

}  // namespace qota
