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

namespace {
std::string& recorded() {
  static std::string line;
  return line;
}
}  // namespace

std::string commandLine() { return recorded(); }

void recordCommandLine(int argc, const char* const* argv) {
  std::string line;
  for (int i = 0; i < argc; ++i) {
    std::string a = i == 0 ? "qota" : argv[i];
    const bool plain = !a.empty() && a.find_first_not_of(
                                         "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789"
                                         "_-+=.,:/@%") == std::string::npos;
    if (!plain) {  // single quotes, a quote inside as '\''
      std::string q = "'";
      for (char c : a) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
      a = q + "'";
    }
    line += (i ? " " : "") + a;
  }
  recorded() = line;
}

}  // namespace qota::tools
