#include <GeographicLib/Config.h>
#include <gdal.h>
#include <proj.h>

#include <string>

#include "qota/version.hpp"
#include "qota_tools.hpp"

namespace qota::tools {

std::string versionText() {
  // GDAL and PROJ as loaded at run time (a shared library may be newer than the headers);
  // GeographicLib as compiled in.
  return std::string("qota ") + QOTA_VERSION_STRING + "\nGDAL " + GDALVersionInfo("RELEASE_NAME") + "\nPROJ " +
         proj_info().version + "\nGeographicLib " + GEOGRAPHICLIB_VERSION_STRING;
}

}  // namespace qota::tools
