// Builder (mesh_readers.hpp): vertices shared by exact position, names, and faces kept whole or
// cut into triangles (triangulate.hpp), for every reader.

#include <Eigen/Core>
#include <algorithm>
#include <bit>
#include <limits>
#include <string>

#include "mesh_readers.hpp"
#include "qota/error.hpp"
#include "triangulate.hpp"

namespace qota::detail {
namespace {

// The largest coordinate a mesh may have (see Builder::vertex).
constexpr double kMaxCoordinate = 1e100;

}  // namespace

std::size_t PointHash::operator()(const PointKey& k) const {
  // Adding 0.0 turns -0 into +0, so that equal keys hash equally.
  std::uint64_t h = 0xcbf29ce484222325ull;
  for (double d : {k.x + 0.0, k.y + 0.0, k.z + 0.0}) {
    h ^= std::bit_cast<std::uint64_t>(d);
    h *= 0x100000001b3ull;
    h ^= h >> 29;
  }
  return static_cast<std::size_t>(h);
}

std::uint32_t Builder::vertex(const Eigen::Vector3d& p) {
  // Coordinates whose products stay in the range of doubles (the exact predicates multiply
  // coordinate differences): finite and within 1e100 in magnitude.
  if (!(p.cwiseAbs().maxCoeff() <= kMaxCoordinate)) {
    throw Error(out_.path + ": vertex " + std::to_string(out_.mesh.vertices.size() + 1) + " (" + std::to_string(p.x()) +
                ", " + std::to_string(p.y()) + ", " + std::to_string(p.z()) +
                ") is not finite or beyond 1e100; shift the model to a local origin");
  }
  const auto [it, added] =
      ids_.try_emplace(PointKey{p.x(), p.y(), p.z()}, static_cast<std::uint32_t>(out_.mesh.vertices.size()));
  if (added) {
    if (out_.mesh.vertices.size() >= std::numeric_limits<std::uint32_t>::max() - 1) {
      throw Error(out_.path + ": more than 2^32 - 2 vertices; split the file");
    }
    out_.mesh.vertices.push_back(p);
  }
  return it->second;
}

void Builder::addFace(std::vector<std::vector<std::uint32_t>> rings, std::uint32_t material, std::uint32_t object,
                      std::uint64_t source, const Where& where) {
  std::vector<std::uint32_t> raw;
  if (options_.keepDegenerate) raw = rings[0];
  for (auto& ring : rings) dropRepeats(ring);

  if (degenerate(rings[0])) {
    ++out_.degenerate;
    if (options_.keepDegenerate && raw.size() >= 3) emit(raw, material, object, source);
    return;
  }
  const std::vector<std::uint32_t>& outline = rings[0];
  // Holes with no area cut nothing out.
  std::vector<std::vector<std::uint32_t>> holes;
  for (std::size_t r = 1; r < rings.size(); ++r) {
    if (!degenerate(rings[r])) holes.push_back(std::move(rings[r]));
  }
  const FaceCut cut = cutFace(outline, holes, out_.mesh.vertices, !options_.triangulate);
  switch (cut.status) {
    case FaceCut::whole:
      emit(outline, material, object, source);
      return;
    case FaceCut::holesNotJoined:
      throw Error(where() +
                  ": cannot join the polygon's holes to its outline (a hole outside it, "
                  "or rings that cross)");
    case FaceCut::notSimple:
      throw Error(where() + ": cannot cut the " + std::to_string(outline.size()) +
                  "-corner polygon into triangles: its outline crosses itself" +
                  (holes.empty() ? "" : " or its holes"));
    case FaceCut::triangles:
      break;
  }
  ++out_.triangulated;
  for (const auto& t : cut.pieces) emit(t, material, object, source);
}

void Builder::finish() {
  if (out_.mesh.polygonCount() == 0) {
    throw Error(out_.path + ": no polygons" +
                (out_.degenerate ? " (all " + std::to_string(out_.degenerate) + " faces are degenerate: no area)"
                                 : std::string()));
  }
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;
  for (const auto& p : out_.mesh.vertices) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  out_.origin = 0.5 * lo + 0.5 * hi;
}

std::uint32_t Builder::named(const std::string& name, std::unordered_map<std::string, std::uint32_t>& ids,
                             std::vector<std::string>& names) {
  const auto [it, added] = ids.try_emplace(name, static_cast<std::uint32_t>(names.size()));
  if (added) names.push_back(name);
  return it->second;
}

void Builder::dropRepeats(std::vector<std::uint32_t>& ring) {
  ring.erase(std::unique(ring.begin(), ring.end()), ring.end());
  while (ring.size() > 1 && ring.front() == ring.back()) ring.pop_back();
}

bool Builder::degenerate(const std::vector<std::uint32_t>& ring) const {
  if (ring.size() < 3) return true;
  const auto& v = out_.mesh.vertices;
  const std::uint32_t a = ring[0], b = ring[1];  // distinct after dropRepeats
  for (std::size_t i = 2; i < ring.size(); ++i) {
    if (ring[i] != a && ring[i] != b && !collinear3(v[a], v[b], v[ring[i]])) return false;
  }
  return true;
}

void Builder::emit(std::span<const std::uint32_t> corners, std::uint32_t material, std::uint32_t object,
                   std::uint64_t source) {
  if (corners.size() == 3) {
    out_.mesh.addTriangle(corners[0], corners[1], corners[2]);
  } else {
    out_.mesh.addPolygon(corners);
  }
  out_.polygonMaterial.push_back(material);
  out_.polygonObject.push_back(object);
  out_.polygonSource.push_back(source);
}

}  // namespace qota::detail
