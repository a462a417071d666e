// Tree files (.qota): a built QOTA index on disk, loaded instead of rebuilt.
//
// Layout (little-endian, as the machine that wrote it; a file from a big-endian machine is
// refused by its magic):
//   magic "QOTATREE", u32 version (3), u32 kind (the mapping's place in AnyMapping's list:
//   0 cartesian, 1 spherical, 2 cylindrical, 3 geodetic, 4 enu), u64 payload bytes, u64 checksum
//   of the payload;
//   payload: the mapping's describe() text (parseMapping reads it back exactly), the source
//   (path, CRS WKT, raster size, geotransform, band and vertical unit when it was a raster), the
//   index's scalars and
//   statistics, then its flat arrays (triangle records, vertex tables, quadtree nodes, leaf
//   references), each as a u64 element count, a u32 element size and the raw elements.
// Structs are stored as they are and have no padding, so the same index always makes the same
// bytes, whatever the machine's threads or the output's name.
// The checksum is a 64-bit multiply-xor hash over the payload's 8-byte words: it catches
// truncation, bit rot and edits, not deliberate forgery. Loading checks the magic, version,
// kind, every size against the bytes left in the file (so nothing large is allocated for a
// truncated file), the checksum, and then the structure itself (every node, reference, corner
// and list index in range, the tree's depth within its table of cut sizes), so a damaged or
// altered file is a clear qota::Error naming the file, never a crash. The quadtree's jump table
// is rebuilt on load (a pass over the nodes).
//
// Files are written to a temporary name in the same folder and renamed into place.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <variant>

#include "qota/any_index.hpp"

namespace qota {

// What a tree was built from, kept so that tools can treat a tree file like its source (a
// raster's footprint and CRS for `qota sample`).
struct TreeSource {
  std::string path;
  std::string crsWkt;
  int width = 0, height = 0;  // raster size; 0 when the source was not a raster
  std::array<double, 6> geotransform{0, 1, 0, 0, 0, 1};
  int band = 1;              // the raster band the heights came from
  std::string verticalUnit;  // the raster's vertical unit ("" when it said nothing)
  double metresPerUnit = 1;  // of that unit
  // On an ellipsoid (the geodetic mapping): what the raster's heights were over (qota/geoid.hpp),
  // said as HeightReference::describe says it, and its geoid grid's path ("" for the ellipsoid);
  // the index holds heights over the ellipsoid, and the tools turn them back. Tree files before
  // version 4: the ellipsoid.
  std::string heightRef = {};
  std::string geoidGrid = {};
};

struct TreeFile {
  AnyIndex index;
  TreeSource source;
};

// True when the file starts with the tree-file magic (cheap; for tools choosing a loader).
bool isTreeFile(const std::string& path);

// Writes an index. Throws qota::Error naming the file when it cannot be written.
void saveTree(const std::string& path, const AnyIndex& index, const TreeSource& source = {});
template <class Index>
void saveTree(const std::string& path, const Index& index, const TreeSource& source = {});

// Reads an index back. Throws qota::Error naming the file and what is wrong; a file of another
// version (2, before qota kept the raster's band and unit) says to rebuild it.
TreeFile loadTree(const std::string& path);

}  // namespace qota
