// What the mesh readers share (private to lib/sources: not a public qota/ header). loadMeshFile
// (mesh_io.cpp) picks a reader; each reader fills a MeshFile through a Builder; OGR and Assimp
// run in a child process (readIsolated).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <unordered_map>
#include <vector>

#include "qota/mesh_io.hpp"

namespace qota::detail {

// ---------------------------------------------------------------------------------------------
// Vertex sharing: one vertex per exact coordinate triple.

struct PointKey {
  double x, y, z;
  bool operator==(const PointKey&) const = default;  // -0 == +0, as wanted
};

struct PointHash {
  std::size_t operator()(const PointKey& k) const;
};

// ---------------------------------------------------------------------------------------------
// Collects vertices, polygons and their names for every reader (mesh_builder.cpp).

class Builder {
 public:
  using Where = std::function<std::string()>;  // describes the face for messages, on demand

  Builder(MeshFile& out, const MeshFileOptions& options) : out_(out), options_(options) {}

  std::uint32_t vertex(const Eigen::Vector3d& p);

  std::uint32_t material(const std::string& name) { return named(name, materialIds_, out_.materials); }
  std::uint32_t object(const std::string& name) { return named(name, objectIds_, out_.objects); }

  // rings[0] is the outline, any further rings are holes. Corners are mesh vertex indices.
  void addFace(std::vector<std::vector<std::uint32_t>> rings, std::uint32_t material, std::uint32_t object,
               std::uint64_t source, const Where& where);

  // The origin, and the one check every reader shares: there is something to query.
  void finish();

 private:
  static std::uint32_t named(const std::string& name, std::unordered_map<std::string, std::uint32_t>& ids,
                             std::vector<std::string>& names);

  // Removes repeated consecutive corners, the closing repeat of the first corner included.
  static void dropRepeats(std::vector<std::uint32_t>& ring);

  // Fewer than three distinct corners, or all exactly on one line.
  bool degenerate(const std::vector<std::uint32_t>& ring) const;

  void emit(std::span<const std::uint32_t> corners, std::uint32_t material, std::uint32_t object, std::uint64_t source);

  MeshFile& out_;
  const MeshFileOptions& options_;
  std::unordered_map<PointKey, std::uint32_t, PointHash> ids_;
  std::unordered_map<std::string, std::uint32_t> materialIds_, objectIds_;
};

// ---------------------------------------------------------------------------------------------
// The readers. Each fills `out` (whose path is set) and calls Builder::finish; errors are
// qota::Error naming the file.

// Wavefront OBJ, in double precision (mesh_obj.cpp).
void readObj(MeshFile& out, const MeshFileOptions& options);
// Any format Assimp reads by the extension `ext` (lower case, no dot) (mesh_assimp.cpp).
void readAssimp(MeshFile& out, const MeshFileOptions& options, const std::string& ext);
// A GDAL/OGR vector dataset; GDAL must be registered (mesh_ogr.cpp).
void readOgr(MeshFile& out, const MeshFileOptions& options);

// Runs read(out) in a child process and takes its MeshFile back, within
// MeshFileOptions::readerSeconds plus a second per 5 MB of file; `reader` names the library in
// messages. A crash, a hang or a garbled reply is a qota::Error naming the file
// (mesh_isolation.cpp).
void readIsolated(MeshFile& out, const MeshFileOptions& options, const char* reader,
                  const std::function<void(MeshFile&)>& read);

}  // namespace qota::detail
