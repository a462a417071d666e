// The public entry points of qota/mesh_io.hpp: loadMeshFile picks a reader by the file's name
// (mesh_readers.hpp), and MeshFile's look-ups.

#include "qota/mesh_io.hpp"

#include <gdal.h>

#include <algorithm>
#include <assimp/Importer.hpp>
#include <cctype>
#include <filesystem>
#include <string>

#include "qota/dem.hpp"  // ensureGdalRegistered
#include "gdal_errors.hpp"
#include "mesh_readers.hpp"
#include "qota/error.hpp"

namespace qota {
namespace {

using detail::QuietGdalErrors;

std::string lowerExtension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  if (!ext.empty()) ext.erase(0, 1);
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}

// Names GDAL opens that are not files: /vsi paths and connection strings ("PG:...").
bool gdalOnlyName(const std::string& path) {
  if (path.rfind("/vsi", 0) == 0) return true;
  const std::size_t colon = path.find(':');
  return colon != std::string::npos && colon > 1 && path.find('/') > colon;
}

}  // namespace

std::int64_t MeshFile::materialIndex(std::string_view name) const {
  const auto it = std::find(materials.begin(), materials.end(), name);
  return it == materials.end() ? -1 : it - materials.begin();
}

std::int64_t MeshFile::objectIndex(std::string_view name) const {
  const auto it = std::find(objects.begin(), objects.end(), name);
  return it == objects.end() ? -1 : it - objects.begin();
}

MeshFile loadMeshFile(const std::string& path, const MeshFileOptions& options) {
  MeshFile out;
  out.path = path;
  std::error_code ec;
  const bool exists = std::filesystem::exists(path, ec);
  if (!exists && !gdalOnlyName(path)) throw Error(path + ": no such file");
  const std::string ext = lowerExtension(path);

  if (ext == "obj") {
    out.format = "obj";
    detail::readObj(out, options);
    return out;
  }

  ensureGdalRegistered();
  {
    QuietGdalErrors quiet;
    // A file a GDAL vector driver recognises goes to OGR first: doubles, and the CRS.
    const bool gdalKnows = !exists || GDALIdentifyDriverEx(path.c_str(), GDAL_OF_VECTOR, nullptr, nullptr);
    if (gdalKnows) {
      detail::readIsolated(out, options, "GDAL/OGR", [&](MeshFile& m) { detail::readOgr(m, options); });
      return out;
    }
  }
  Assimp::Importer importer;
  if (!ext.empty() && importer.IsExtensionSupported(ext)) {
    detail::readIsolated(out, options, "Assimp", [&](MeshFile& m) { detail::readAssimp(m, options, ext); });
    return out;
  }
  throw Error(path +
              ": unknown format: not OBJ, not a mesh format Assimp reads (by extension), "
              "not a vector dataset GDAL recognises");
}

}  // namespace qota
