// The edits' ledger every index keeps (insertPolygon, removePolygon): which polygons are removed,
// and which triangles each polygon has (built on the first removal: an index never edited keeps
// no map).
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <unordered_map>
#include <vector>

namespace qota {

class PolygonLedger {
 public:
  bool removed(std::uint32_t polygon) const { return polygon < removed_.size() && removed_[polygon]; }
  // False while no polygon was ever removed: then no lookup is needed (nor the polygon's id).
  bool anyRemoved() const { return !removed_.empty(); }

  // Triangle `triangle` was added for `polygon` (an insertion).
  void added(std::uint32_t polygon, std::uint32_t triangle) {
    if (!trianglesOf_.empty()) trianglesOf_.emplace(polygon, triangle);
  }

  // Takes `polygon` out: nullopt when it is not one of the first `polygons` or is removed
  // already; else calls visit(t) for each of its triangles and returns how many there were.
  // polygonOf(t) is triangle t's polygon, for t below `triangles` (to build the map once).
  template <class PolygonOf, class Visit>
  std::optional<std::size_t> remove(std::uint32_t polygon, std::uint64_t polygons, std::size_t triangles,
                                    const PolygonOf& polygonOf, const Visit& visit) {
    if (polygon >= polygons) return std::nullopt;
    if (removed_.size() < polygons) removed_.resize(polygons, 0);
    if (removed_[polygon]) return std::nullopt;
    if (trianglesOf_.empty()) {
      trianglesOf_.reserve(triangles);
      for (std::size_t t = 0; t < triangles; ++t) {
        trianglesOf_.emplace(polygonOf(t), static_cast<std::uint32_t>(t));
      }
    }
    removed_[polygon] = 1;
    std::size_t count = 0;
    const auto [first, last] = trianglesOf_.equal_range(polygon);
    for (auto it = first; it != last; ++it, ++count) visit(it->second);
    trianglesOf_.erase(polygon);
    return count;
  }

  // The removed flags, one byte a polygon (as far as any was removed): what tree files store.
  std::vector<std::uint8_t>& flags() { return removed_; }
  const std::vector<std::uint8_t>& flags() const { return removed_; }

 private:
  std::vector<std::uint8_t> removed_;
  std::unordered_multimap<std::uint32_t, std::uint32_t> trianglesOf_;
};

}  // namespace qota
