// GDAL error plumbing shared by the library's and the tools' GDAL code (not part of the public
// qota/ headers: it needs GDAL's own).
#pragma once

#include <cpl_error.h>

#include <string>

namespace qota::detail {

// Keeps GDAL from printing its own errors while we turn them into a qota::Error (or decide they
// are none, as when probing whether a file is a raster).
struct QuietGdalErrors {
  QuietGdalErrors() {
    CPLPushErrorHandler(CPLQuietErrorHandler);
    CPLErrorReset();
  }
  ~QuietGdalErrors() { CPLPopErrorHandler(); }
  QuietGdalErrors(const QuietGdalErrors&) = delete;
  QuietGdalErrors& operator=(const QuietGdalErrors&) = delete;
};

// GDAL's last error as ": message", or "" when there is none.
inline std::string gdalMessage() {
  const char* m = CPLGetLastErrorMsg();
  return (m && *m) ? std::string(": ") + m : std::string();
}

}  // namespace qota::detail
