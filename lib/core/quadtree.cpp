#include "qota/quadtree.hpp"

#include <algorithm>
#include <atomic>

#include <cmath>
#include <string>

#include "qota/error.hpp"
#include "qota/memory_budget.hpp"

namespace qota {

void Quadtree::tooManyReferences() const {
  throw Error("quadtree: more than " + std::to_string(refBudget_) + " leaf references for " +
              std::to_string(itemCount_) + " polygons; Maxpoly " + std::to_string(options_.maxPoly) +
              " is smaller than the number of polygons that share an edge or overlap here, so "
              "leaves split down to Maxdepth " +
              std::to_string(options_.maxDepth) + ": raise Maxpoly or lower Maxdepth");
}

void Quadtree::checkMemoryLeft() const {
  // Enough for the rest of a level's lists and the final copies of the node and reference arrays.
  const std::uint64_t reserve = 128ull * (1ull << 20) + 12ull * nodes_.size();
  const std::uint64_t left = memory::availableBytes();
  if (left != 0 && left < reserve) {
    throw Error("quadtree: " + std::to_string(nodes_.size()) + " nodes and " + std::to_string(refs_.size()) +
                " leaf references for " + std::to_string(itemCount_) + " polygons leave " + memory::gib(left) +
                " of memory: the polygons are too thin or overlap too much for Maxpoly " +
                std::to_string(options_.maxPoly) + " and Maxdepth " + std::to_string(options_.maxDepth) +
                "; raise Maxpoly or lower Maxdepth");
  }
}

std::uint32_t Quadtree::leafIndex(double u, double v) const {
  std::uint32_t n = 0;
  double lu = root_.ulo, lv = root_.vlo;
  for (std::uint32_t d = 0; nodes_[n].count == kInner; ++d) {
    const Point2 c = cutOf(n, d, lu, lv);
    const bool hu = u >= c.u, hv = v >= c.v;
    lu = hu ? c.u : lu;
    lv = hv ? c.v : lv;
    n = nodes_[n].first + (static_cast<std::uint32_t>(hv) << 1 | static_cast<std::uint32_t>(hu));
  }
  return n;
}

// The cost model's cut of a node (QuadtreeOptions::Cuts::CostModel). Along each axis separately,
// the items' bounding boxes are binned into 16 slices; a cut at slice boundary j leaves on the
// low side the items starting before it and on the high side those ending at or after it, and
// costs j * low + (16 - j) * high (expected tests, by area share). The cheapest of the 9
// boundaries in the middle half wins; ties keep the midpoint.
Point2 Quadtree::costCut(const Box2& box, std::uint32_t depth, std::span<const std::uint32_t> items) const {
  constexpr int kBins = 16;
  std::uint32_t startU[kBins] = {}, endU[kBins] = {}, startV[kBins] = {}, endV[kBins] = {};
  const double su = box.uhi - box.ulo, sv = box.vhi - box.vlo;
  const double scaleU = kBins / su, scaleV = kBins / sv;
  auto bin = [](double x, double lo, double scale) {
    const double b = (x - lo) * scale;  // NaN-safe: a NaN lands in bin 0
    return !(b > 0) ? 0 : b >= kBins - 1 ? kBins - 1 : static_cast<int>(b);
  };
  for (std::uint32_t it : items) {
    const Box2 b = boxOf_(it);
    ++startU[bin(b.ulo, box.ulo, scaleU)], ++endU[bin(b.uhi, box.ulo, scaleU)];
    ++startV[bin(b.vlo, box.vlo, scaleV)], ++endV[bin(b.vhi, box.vlo, scaleV)];
  }
  auto best = [&](const std::uint32_t* start, const std::uint32_t* end, double lo, double size, double mid) {
    std::uint64_t low[kBins + 1] = {}, high[kBins + 1] = {};
    for (int j = 1; j <= kBins; ++j) low[j] = low[j - 1] + start[j - 1];
    for (int j = kBins - 1; j >= 0; --j) high[j] = high[j + 1] + end[j];
    int pick = kBins / 2;
    auto cost = [&](int j) { return j * low[j] + (kBins - j) * high[j]; };
    // Within the middle half of the box: a cut nearer the side leaves a sliver of a child that
    // the size floor and Maxdepth then cannot split usefully.
    for (int j = kBins / 4; j <= 3 * kBins / 4; ++j) {
      if (cost(j) < cost(pick)) pick = j;
    }
    const double cut = lo + size * pick / kBins;
    return pick == kBins / 2 || !(cut > lo && cut < lo + size) ? mid : cut;
  };
  return {best(startU, endU, box.ulo, su, box.ulo + half_[depth].u),
          best(startV, endV, box.vlo, sv, box.vlo + half_[depth].v)};
}

Quadtree::Node Quadtree::descend(double u, double v, Cursor& cursor) const {
  cursor.leaf = descend(u, v, cursor.box);
  cursor.stamp = stamp_;
  return cursor.leaf;
}

Quadtree::Node Quadtree::descend(double u, double v, Box2& box) const {
  // leafNode's descent, also tracking the high edges of the box: a low child's high edge is the
  // cut itself, a high child's is its parent's.
  Node nd = nodes_[0];
  std::uint32_t d = 0, n = 0;
  double lu = root_.ulo, lv = root_.vlo, hu = root_.uhi, hv = root_.vhi;
  if (jumpDepth_) {
    const std::uint32_t ix = jumpColumn(u, cutU_, jumpScaleU_, root_.ulo);
    const std::uint32_t iy = jumpColumn(v, cutV_, jumpScaleV_, root_.vlo);
    nd = jump_[(iy << jumpDepth_) | ix];
    lu = cutU_[ix], lv = cutV_[iy];
    hu = ix + 1 < cutU_.size() ? cutU_[ix + 1] : root_.uhi;
    hv = iy + 1 < cutV_.size() ? cutV_[iy + 1] : root_.vhi;
    d = jumpDepth_;
  }
  for (; nd.count == kInner; ++d) {
    // (With stored cuts there is no jump table, so n is the node's index throughout.)
    const Point2 c = cutOf(n, d, lu, lv);
    const double mu = c.u, mv = c.v;
    const bool highU = u >= mu, highV = v >= mv;
    (highU ? lu : hu) = mu;
    (highV ? lv : hv) = mv;
    n = nd.first + (static_cast<std::uint32_t>(highV) << 1 | static_cast<std::uint32_t>(highU));
    nd = nodes_[n];
  }
  box = {lu, lv, hu, hv};
  return nd;
}

std::uint64_t nextSerial() {
  static std::atomic<std::uint64_t> next{1};
  return next++;
}

bool Quadtree::leafPast(const Box2& b, double u, double v, double du, double dv, Node& leaf, Box2& box) const {
  // The steps to the box's far side along each axis; the first whole number past the nearer.
  const double tu = du > 0 ? (b.uhi - u) / du : du < 0 ? (b.ulo - u) / du : INFINITY;
  const double tv = dv > 0 ? (b.vhi - v) / dv : dv < 0 ? (b.vlo - v) / dv : INFINITY;
  const double steps = std::floor(std::min(tu, tv)) + 1;
  if (!(steps >= 1 && steps <= 64)) return false;
  const double qu = u + steps * du, qv = v + steps * dv;
  if (!contains(qu, qv)) return false;
  leaf = descend(qu, qv, box);
  return true;
}

Quadtree::Node Quadtree::lookAhead(double u, double v, bool sameTree, Cursor& cursor) const {
  const double du = u - cursor.lastU, dv = v - cursor.lastV;  // (NaN on a cursor's first query)
  const Box2& b = cursor.box;
  // A cursor moved by steps as large as its leaves (or at random) gains nothing, and the
  // descents ahead would cost it misses of their own; so does a tree that stays in cache.
  const bool walking = fetchAhead_ && std::fabs(du) <= 0.5 * (b.uhi - b.ulo) &&
                       std::fabs(dv) <= 0.5 * (b.vhi - b.vlo) && (du != 0 || dv != 0) && sameTree;
  constexpr int K = Cursor::kAhead;
  if (!walking) {
    cursor.nextCount = 0;
    return Node{0, 0};
  }
  const auto fetch = [this](const Node& leaf) {
    if (leaf.count == kInner || leafSize(leaf) == 0) return;
    const std::uint32_t* r = refs_.data() + leaf.first;
    __builtin_prefetch(r);
    __builtin_prefetch(r + leafSize(leaf) - 1);
  };
  const auto same = [](const Node& x, const Node& y) { return x.first == y.first && x.count == y.count; };
  // Extends the course from leaf i - 1 (or the cursor's) to leaf i, ..., K - 1.
  const auto extend = [&](int i) {
    for (cursor.nextCount = i; cursor.nextCount < K; ++cursor.nextCount) {
      const Box2& from = cursor.nextCount == 0 ? b : cursor.nextBox[cursor.nextCount - 1];
      if (!leafPast(from, u, v, du, dv, cursor.next[cursor.nextCount], cursor.nextBox[cursor.nextCount])) return;
      fetch(cursor.next[cursor.nextCount]);
    }
  };
  if (cursor.nextCount == K && same(cursor.next[0], cursor.leaf)) {
    // On course: the leaf after this one had its references fetched a leaf ago, so its items can
    // be fetched now; the one after it is new.
    for (int i = 0; i + 1 < K; ++i) cursor.next[i] = cursor.next[i + 1], cursor.nextBox[i] = cursor.nextBox[i + 1];
    extend(K - 1);
    return cursor.next[0];
  }
  extend(0);  // a new course: the leaves ahead found again, their items fetched on the next
  return Node{0, 0};
}

void Quadtree::refreshJump(std::uint32_t n, std::uint32_t depth, const Box2& box) {
  if (jumpDepth_ == 0 || depth > jumpDepth_) return;  // deeper: the table holds an ancestor
  if (depth < jumpDepth_ && nodes_[n].count == kInner) {
    // A node above the table's depth that is (now) inner: the table holds its descendants.
    const Node nd = nodes_[n];
    const double mu = box.ulo + half_[depth].u, mv = box.vlo + half_[depth].v;
    refreshJump(nd.first, depth + 1, {box.ulo, box.vlo, mu, mv});
    refreshJump(nd.first + 1, depth + 1, {mu, box.vlo, box.uhi, mv});
    refreshJump(nd.first + 2, depth + 1, {box.ulo, mv, mu, box.vhi});
    refreshJump(nd.first + 3, depth + 1, {mu, mv, box.uhi, box.vhi});
    return;
  }
  // The node's box starts on a cut of the table exactly (the same sums), and spans
  // 2^(jumpDepth - depth) cells each way.
  const auto ix = static_cast<std::uint32_t>(std::lower_bound(cutU_.begin(), cutU_.end(), box.ulo) - cutU_.begin());
  const auto iy = static_cast<std::uint32_t>(std::lower_bound(cutV_.begin(), cutV_.end(), box.vlo) - cutV_.begin());
  const std::uint32_t span = 1u << (jumpDepth_ - depth);
  for (std::uint32_t y = iy; y < iy + span && y < cutV_.size(); ++y) {
    for (std::uint32_t x = ix; x < ix + span && x < cutU_.size(); ++x) {
      jump_[(y << jumpDepth_) | x] = nodes_[n];
    }
  }
}

void Quadtree::compact() {
  // Copy every leaf's live range into a fresh array, in node order.
  BigVector<std::uint32_t> fresh;
  fresh.reserve(refs_.size() - abandoned_);
  for (Node& n : nodes_) {
    if (n.count == kInner) continue;
    const std::uint32_t first = static_cast<std::uint32_t>(fresh.size());
    fresh.insert(fresh.end(), refs_.begin() + n.first, refs_.begin() + n.first + leafSize(n));
    n.first = first;
  }
  refs_.swap(fresh);
  abandoned_ = 0;
  buildJumpTable();  // it holds copies of the leaves
}

void Quadtree::buildJumpTable() {
  stamp_ = nextSerial();  // (the end of every build, markLeaves and compaction, and a tree file's load)
  // A tree within a few MiB (with its items' records, some more) stays in cache while it is
  // walked: nothing to fetch ahead.
  fetchAhead_ = nodes_.size() * sizeof(Node) + refs_.size() * sizeof(std::uint32_t) > (4u << 20);
  jumpDepth_ = 0;
  cutU_.clear(), cutV_.clear(), jump_.clear();
  if (!cut_.empty()) return;  // the table's uniform cells are the midpoint cuts' alone
  // Depth of the tree, and its leaf count, decide the table's depth: about one cell per leaf (so
  // most queries land on their leaf at once), at most 4^11 cells (16 MiB).
  std::uint32_t depth = 0, leaves = 0;
  forEachLeaf([&](const Node&, std::uint32_t d) {
    ++leaves;
    depth = std::max(depth, d);
  });
  std::uint32_t k = 0;
  while (k < depth && k < 11 && (std::uint64_t{1} << (2 * (k + 1))) <= 2ull * leaves) ++k;
  if (k < 2) return;  // a tree this small descends in a few compares anyway

  // The cut positions exactly as the descent sums them: column i's low edge adds half[d] for
  // every bit d of i (most significant first).
  const std::uint32_t n = 1u << k;
  auto cuts = [&](double lo, bool alongU) {
    std::vector<double> c(n);
    for (std::uint32_t i = 0; i < n; ++i) {
      double x = lo;
      for (std::uint32_t d = 0; d < k; ++d) {
        if (i >> (k - 1 - d) & 1u) x = x + (alongU ? half_[d].u : half_[d].v);
      }
      c[i] = x;
    }
    return c;
  };
  cutU_ = cuts(root_.ulo, true);
  cutV_ = cuts(root_.vlo, false);
  // A binary search over the cuts is the descent only while they increase (they do unless the
  // cells are near the coordinates' rounding); otherwise go without the table.
  for (std::uint32_t i = 1; i < n; ++i) {
    if (!(cutU_[i] > cutU_[i - 1]) || !(cutV_[i] > cutV_[i - 1])) {
      cutU_.clear(), cutV_.clear();
      return;
    }
  }
  jump_.assign(std::size_t{n} * n, Node{0, 0});
  struct Cell {
    std::uint32_t node, depth, ix, iy;  // ix, iy: the node's first cell at depth k
  };
  std::vector<Cell> todo{{0, 0, 0, 0}};
  while (!todo.empty()) {
    const Cell c = todo.back();
    todo.pop_back();
    const Node& nd = nodes_[c.node];
    if (nd.count == kInner && c.depth < k) {
      const std::uint32_t step = 1u << (k - c.depth - 1);
      for (std::uint32_t q = 0; q < 4; ++q) {
        todo.push_back({nd.first + q, c.depth + 1, c.ix + (q & 1u) * step, c.iy + (q >> 1) * step});
      }
      continue;
    }
    const std::uint32_t span = 1u << (k - c.depth);
    for (std::uint32_t y = c.iy; y < c.iy + span; ++y) {
      std::fill_n(jump_.begin() + (std::size_t{y} << k) + c.ix, span, nd);
    }
  }
  jumpDepth_ = k;
  jumpScaleU_ = n / (root_.uhi - root_.ulo);
  jumpScaleV_ = n / (root_.vhi - root_.vlo);
}

QuadtreeStats Quadtree::stats() const {
  QuadtreeStats s;
  s.nodes = nodes_.size();
  s.references = refs_.size();
  s.memoryBytes = nodes_.size() * sizeof(Node) + refs_.size() * sizeof(std::uint32_t) + half_.size() * sizeof(Half) +
                  jump_.size() * sizeof(Node) + cut_.size() * sizeof(Point2) +
                  (cutU_.size() + cutV_.size()) * sizeof(double);
  // Walk the tree to learn each leaf's depth; a leaf at depth d covers 4^-d of the domain.
  // With stored cuts a leaf's share is its box's area over the root's.
  struct Item {
    std::uint32_t node, depth;
    Box2 box;
  };
  std::vector<Item> stack{{0, 0, root_}};
  double weighted = 0;
  const double rootArea = (root_.uhi - root_.ulo) * (root_.vhi - root_.vlo);
  while (!stack.empty()) {
    const Item it = stack.back();
    stack.pop_back();
    const Node& n = nodes_[it.node];
    if (n.count == kInner) {
      const Box2& b = it.box;
      const Point2 c = cutOf(it.node, it.depth, b.ulo, b.vlo);
      stack.push_back({n.first, it.depth + 1, {b.ulo, b.vlo, c.u, c.v}});
      stack.push_back({n.first + 1, it.depth + 1, {c.u, b.vlo, b.uhi, c.v}});
      stack.push_back({n.first + 2, it.depth + 1, {b.ulo, c.v, c.u, b.vhi}});
      stack.push_back({n.first + 3, it.depth + 1, {c.u, c.v, b.uhi, b.vhi}});
      continue;
    }
    const std::uint32_t count = leafSize(n);
    ++s.leaves;
    if (count == 0) ++s.emptyLeaves;
    s.depth = std::max(s.depth, it.depth);
    s.maxLeafItems = std::max(s.maxLeafItems, count);
    weighted += cut_.empty() || !(rootArea > 0)
                    ? std::ldexp(static_cast<double>(count), -2 * static_cast<int>(it.depth))
                    : count * ((it.box.uhi - it.box.ulo) * (it.box.vhi - it.box.vlo) / rootArea);
  }
  s.meanLeafItems = s.leaves ? static_cast<double>(s.references) / static_cast<double>(s.leaves) : 0;
  s.averageTests = weighted;
  return s;
}

}  // namespace qota
