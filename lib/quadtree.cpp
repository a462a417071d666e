#include "qota/quadtree.hpp"

#include <cmath>

namespace qota {

QuadtreeStats Quadtree::stats() const {
  QuadtreeStats s;
  s.nodes = nodes_.size();
  s.references = refs_.size();
  s.memoryBytes = nodes_.size() * sizeof(Node) + refs_.size() * sizeof(std::uint32_t) +
                  half_.size() * sizeof(Half);
  // Walk the tree to learn each leaf's depth; a leaf at depth d covers 4^-d of the domain.
  struct Item {
    std::uint32_t node, depth;
  };
  std::vector<Item> stack{{0, 0}};
  double weighted = 0;
  while (!stack.empty()) {
    const Item it = stack.back();
    stack.pop_back();
    const Node& n = nodes_[it.node];
    if (n.count == kInner) {
      for (std::uint32_t c = 0; c < 4; ++c) stack.push_back({n.first + c, it.depth + 1});
      continue;
    }
    ++s.leaves;
    if (n.count == 0) ++s.emptyLeaves;
    s.depth = std::max(s.depth, it.depth);
    s.maxLeafItems = std::max(s.maxLeafItems, n.count);
    weighted += std::ldexp(static_cast<double>(n.count), -2 * static_cast<int>(it.depth));
  }
  s.meanLeafItems = s.leaves ? static_cast<double>(s.references) / static_cast<double>(s.leaves) : 0;
  s.averageTests = weighted;
  return s;
}

}  // namespace qota
