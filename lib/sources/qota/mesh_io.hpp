// Terrains from mesh files and 3D vector data: Wavefront OBJ (qota's own reader), every mesh format
// Assimp reads (PLY, STL, glTF, COLLADA, FBX, OFF, 3DS, ...), and every vector dataset GDAL/OGR
// reads with 3D surfaces (GeoPackage, Shapefile, GeoJSON, FlatGeobuf, DXF, ...).
//
// Which reader: a name ending in ".obj" (any case) goes to the OBJ reader; a file a GDAL vector
// driver recognises goes to OGR (so DXF is read by GDAL, in double precision); any other
// extension Assimp knows goes to Assimp; else OGR is tried once more (connection strings, /vsi
// paths) before "unknown format". OGR and Assimp run in a child process with a time limit: a
// crash or a hang in their parsers is an error naming the file, not a crash of qota.
//
// Precision: world coordinates are kept as the file gives them, in double. Debian's Assimp is
// built in single precision (sizeof(ai_real) == 4, checked in the tests): it rounds every
// coordinate to 24 bits, i.e. 1/32 m at y = 447,000 m and 1/4 m at 2e6. City models use such
// absolute map coordinates, so OBJ is read by qota's own parser, which converts the text with
// std::from_chars (correctly rounded: a vertex equals the double nearest its decimal text), and
// OGR gives doubles. Files read through Assimp are flagged with MeshFile::singlePrecision; keep
// their coordinates below about 1e5 in magnitude (shift them to a local origin on export) or
// convert them to OBJ or a GDAL format first.
//
// Vertices: vertices with identical coordinates become one vertex (the first in file order), in
// every reader: the query structure is watertight only between polygons that share vertex
// indices, and STL, OGR rings and per-object OBJ vertex lists repeat shared corners. Node
// transforms (Assimp) are applied in double. Unused vertices of an OBJ file are kept, so that OBJ
// vertex k (1-based) is mesh vertex k - 1 whenever the file has no repeated vertex.
//
// Polygons: every face (OBJ "f", Assimp face of 3 or more corners, OGR polygon or polyhedral
// surface / TIN patch) becomes one polygon of the Mesh, unchanged when it is convex in its own
// plane and has no holes. Repeated consecutive corners (and the closing point of OGR rings) are
// removed first. A face that is not convex, or a polygon with holes (OGR), is cut into triangles
// by ear clipping in the plane it is most nearly parallel to, with exact orientation tests; each
// triangle keeps the face's material, object and source (counted in MeshFile::triangulated). A
// face kept whole that is not planar may still look non-convex along some gravity, which
// CartesianIndex refuses; MeshFileOptions::triangulate cuts every face and so avoids that.
//
// Degenerate faces: fewer than three distinct corners, or all corners exactly on one line in
// double arithmetic. They cover no area, so dropping them never opens a crack; a sliver with any
// area at all is kept, because dropping it would. They are counted in MeshFile::degenerate and
// dropped unless MeshFileOptions::keepDegenerate (then kept as read; CartesianIndex counts them
// as walls).
//
// Materials and objects: OBJ "usemtl" names the material and "o" or "g" the object (the latest
// of either; the mtllib is not read). Assimp: the aiMaterial's name and the node's name (the
// mesh's when the node has none). OGR: the value of MeshFileOptions::materialField, else the
// layer name; the object is "layer:fid". Faces before any usemtl / o / g get the name "".
//
// Frame: coordinates are never reprojected. MeshFile::origin is the centre of the bounding box
// of the vertices; pass it as the CartesianMapping origin so that the index works with small
// coordinates: CartesianMapping(Eigen::Vector3d(0, 0, -1), file.origin).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "qota/mesh.hpp"

namespace qota {

struct MeshFileOptions {
  // OGR: the only layer to read; empty reads every layer whose geometry type can hold surfaces.
  std::string layer;
  // OGR: the attribute field whose value names each feature's material; empty uses the layer name.
  std::string materialField;
  // Keep degenerate faces (see above) instead of dropping them.
  bool keepDegenerate = false;
  // Cut every polygon into triangles, convex ones too (fans of their corners).
  bool triangulate = false;
  // Assimp and OGR read in a child process (their parsers loop or crash on some hostile files); a
  // read that takes longer than this many seconds, plus one per 5 MB of file, is given up as an
  // error.
  double readerSeconds = 60;
};

struct MeshFile {
  std::string path;
  std::string format;  // "obj", "assimp:<extension>" or "ogr:<GDAL driver short name>"
  Mesh mesh;           // world coordinates as in the file, double precision

  std::vector<std::string> materials;          // material or class names, in order of first use
  std::vector<std::uint32_t> polygonMaterial;  // per polygon: index into materials
  std::vector<std::string> objects;            // object names, in order of first use
  std::vector<std::uint32_t> polygonObject;    // per polygon: index into objects
  // Per polygon, where it came from, for messages: OBJ the line of its "f"; OGR the feature id;
  // Assimp the face's index in its aiMesh.
  std::vector<std::uint64_t> polygonSource;

  std::string crsWkt;  // OGR: the CRS of the (first) layer; empty otherwise or when it has none
  // The centre of the vertices' bounding box: the origin to build the mapping with.
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  std::uint64_t degenerate = 0;    // degenerate faces found (dropped unless keepDegenerate)
  std::uint64_t triangulated = 0;  // faces cut into triangles (non-convex or with holes)
  bool singlePrecision = false;    // coordinates went through 32-bit floats (Assimp)

  // Index of the material or object with this name, or -1 when there is none.
  std::int64_t materialIndex(std::string_view name) const;
  std::int64_t objectIndex(std::string_view name) const;
  const std::string& materialOf(std::size_t polygon) const { return materials[polygonMaterial[polygon]]; }
  const std::string& objectOf(std::size_t polygon) const { return objects[polygonObject[polygon]]; }
};

// Reads a mesh file or vector dataset. Throws qota::Error naming the file (and for OBJ the line,
// as "path:line: message"; for OGR the layer and feature) when it does not exist, has an unknown
// format, is malformed (a vertex without three numbers, a face index that is not a number, is 0
// or is out of range, a face of fewer than three corners, 2D OGR geometry, a geometry that is not
// a surface), has a face that cannot be triangulated, or has no polygons.
MeshFile loadMeshFile(const std::string& path, const MeshFileOptions& options = {});

}  // namespace qota
