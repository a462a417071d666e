// The QOTA quadtree over a 2D domain (MERL TR-96-17, section 3): an axis-aligned quadtree whose
// leaves hold references to the items (polygons) whose projection meets them. It knows nothing of
// polygons itself: the build asks an overlap predicate, so every terrain kind reuses it.
//
// Layout: all nodes in one array of 8-byte records with 32-bit indices; the four children of a
// node are consecutive; a leaf is a range of the one reference array. Cuts are at the midpoint of
// the node (the paper's rule), so a node's box is implied by the path to it and is not stored:
// a query descends with two compares per level.
//
// Split rule: the paper's (more than Maxpoly items and above Maxdepth), plus two checks: a node
// whose split would not cut the number of polygon tests of a query on terrain by at least 15%
// stays a leaf, and so does a node smaller than the owner's size floor (typically half a
// polygon), where the items overlap because they are larger than the node and no cut can part
// them.
//
// Boundary rule: a point exactly on a cut line belongs to the child on the high side (u >= mid goes
// to the high-u child). Boxes are closed in the build, so an item touching a cut line is referenced
// from both sides, and the query finds it whichever side it descends to. The midpoints the build
// uses are computed by the same expression as the query's (lo + half[depth]), so the two agree
// bit for bit.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <exception>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include "qota/batch.hpp"
#include "qota/error.hpp"
#include "qota/memory.hpp"
#include "qota/predicates.hpp"
#include "qota/vocabulary.hpp"

namespace qota {

// A number no earlier call in the process returned: what tells a tree's or an index's state from
// every other's, including one built later in the same memory.
std::uint64_t nextSerial();

class Quadtree {
 public:
  static constexpr std::uint32_t kInner = 0xffffffffu;
  // A node is split only when the mean polygon count of its children that hold any is at most
  // this fraction of its own (see buildNode).
  static constexpr double kMinSplitGain = 0.85;
  // A leaf flag set by markLeaves: the leaf's items do not overlap (a single layer of terrain).
  static constexpr std::uint32_t kSingleLayer = 0x80000000u;
  struct Node {
    std::uint32_t first;  // inner: index of the first of 4 children; leaf: first reference
    std::uint32_t count;  // kInner for an inner node, else the leaf's reference count | flags
  };
  static std::uint32_t leafSize(const Node& leaf) { return leaf.count & ~kSingleLayer; }
  static bool singleLayer(const Node& leaf) { return (leaf.count & kSingleLayer) != 0; }

  Quadtree() = default;

  // Builds over items 0..itemCount-1 in the closed box root. overlaps(item, box) must return true
  // whenever the item meets the closed box (it may also return true when in doubt).
  // minSizeU/V: a node smaller than this along both axes is not split (no cut can separate items
  // larger than the node; see CartesianIndex). 0: no floor.
  // boxOf(item): the item's bounding box, for the cost-model cuts (QuadtreeOptions::cuts); empty:
  // midpoint cuts.
  // threads: with midpoint cuts, the root's four subtrees are built on up to this many threads
  // (batch::inSlices: 0, one per hardware thread; overlaps is then called from several at once)
  // and joined in the one thread's layout: the same tree for any count.
  template <class Overlaps>
  void build(std::uint32_t itemCount, Box2 root, const QuadtreeOptions& options, Overlaps&& overlaps,
             double minSizeU = 0, double minSizeV = 0, const std::function<Box2(std::uint32_t)>& boxOf = {},
             unsigned threads = 1);
  // Whether the cuts are stored per node (cost model) rather than at the midpoints.
  bool storedCuts() const { return !cut_.empty(); }
  // The index into nodes() of the leaf containing (u, v). Precondition: contains(u, v).
  std::uint32_t leafIndex(double u, double v) const;

  const Box2& box() const { return root_; }
  const QuadtreeOptions& options() const { return options_; }
  double minSizeU() const { return minSizeU_; }
  double minSizeV() const { return minSizeV_; }
  bool contains(double u, double v) const { return root_.contains(u, v); }

  // The items of the leaf containing (u, v). Precondition: contains(u, v).
  std::span<const std::uint32_t> leafItems(double u, double v) const { return leafRange(leafNode(u, v)); }
  // The leaf containing (u, v), as a copy of its node. Precondition: contains(u, v).
  Node leafNode(double u, double v) const {
    if (!cut_.empty()) {
      // Stored cuts: two compares against the node's own cut a level.
      std::uint32_t n = 0;
      Node nd = nodes_[0];
      while (nd.count == kInner) {
        const Point2 c = cut_[n];
        n = nd.first + (static_cast<std::uint32_t>(v >= c.v) << 1 | static_cast<std::uint32_t>(u >= c.u));
        nd = nodes_[n];
      }
      return nd;
    }
    Node nd = nodes_[0];
    std::uint32_t d = 0;
    double lu = root_.ulo, lv = root_.vlo;
    if (jumpDepth_) {
      // Start at depth jumpDepth_ from the table instead of descending the levels above it; the
      // table holds the node itself, so a leaf at or above that depth costs no node load.
      const std::uint32_t ix = jumpColumn(u, cutU_, jumpScaleU_, root_.ulo);
      const std::uint32_t iy = jumpColumn(v, cutV_, jumpScaleV_, root_.vlo);
      nd = jump_[(iy << jumpDepth_) | ix];
      if (nd.count != kInner) return nd;
      lu = cutU_[ix], lv = cutV_[iy], d = jumpDepth_;
    }
    for (; nd.count == kInner; ++d) {
      const double mu = lu + half_[d].u, mv = lv + half_[d].v;
      const bool hu = u >= mu, hv = v >= mv;
      lu = hu ? mu : lu;
      lv = hv ? mv : lv;
      nd = nodes_[nd.first + (static_cast<std::uint32_t>(hv) << 1 | static_cast<std::uint32_t>(hu))];
    }
    return nd;
  }
  // leafNode's descent in steps, for batches that overlap the cache misses of many points: each
  // step names the next node to read and prefetches it, so a batch can start other points'
  // steps before reading it. startWalk(u, v) starts at the jump table's cell (or the root);
  // stepWalk reads the node the walk is at: a leaf ends the walk (false, the leaf in `leaf`),
  // an inner node moves it to the child holding (u, v) (true). The leaf is leafNode(u, v)'s,
  // by the same expressions. Precondition: contains(u, v).
  struct Walk {
    const Node* at;
    std::uint32_t node, depth;  // node: the index of *at in nodes() (unused in the jump table)
    double lu, lv;
  };
  Walk startWalk(double u, double v) const {
    Walk w{nodes_.data(), 0, 0, root_.ulo, root_.vlo};
    if (jumpDepth_) {
      const std::uint32_t ix = jumpColumn(u, cutU_, jumpScaleU_, root_.ulo);
      const std::uint32_t iy = jumpColumn(v, cutV_, jumpScaleV_, root_.vlo);
      w.at = &jump_[(iy << jumpDepth_) | ix];
      w.lu = cutU_[ix], w.lv = cutV_[iy], w.depth = jumpDepth_;
    }
    __builtin_prefetch(w.at);
    return w;
  }
  bool stepWalk(double u, double v, Walk& w, Node& leaf) const {
    const Node nd = *w.at;
    if (nd.count != kInner) {
      leaf = nd;
      return false;
    }
    // (With stored cuts there is no jump table, so w.node is the node's index throughout.)
    const Point2 c = cutOf(w.node, w.depth, w.lu, w.lv);
    const bool hu = u >= c.u, hv = v >= c.v;
    w.lu = hu ? c.u : w.lu;
    w.lv = hv ? c.v : w.lv;
    w.node = nd.first + (static_cast<std::uint32_t>(hv) << 1 | static_cast<std::uint32_t>(hu));
    w.at = &nodes_[w.node];
    ++w.depth;
    __builtin_prefetch(w.at);
    return true;
  }
  // The index in nodes() of the node containing (u, v) at depth maxDepth, or of the leaf above it
  // (the descent's own cuts, without the jump table): a view of the tree cut at a depth, as
  // qota render-tree draws it. Precondition: contains(u, v).
  std::uint32_t nodeIndexAt(double u, double v, std::uint32_t maxDepth) const {
    std::uint32_t n = 0, d = 0;
    double lu = root_.ulo, lv = root_.vlo;
    while (nodes_[n].count == kInner && d < maxDepth) {
      const Point2 c = cutOf(n, d, lu, lv);
      const bool hu = u >= c.u, hv = v >= c.v;
      lu = hu ? c.u : lu, lv = hv ? c.v : lv;
      n = nodes_[n].first + (static_cast<std::uint32_t>(hv) << 1 | static_cast<std::uint32_t>(hu));
      ++d;
    }
    return n;
  }
  // A query cursor for temporal coherence: the last leaf found and a box of points known to lie
  // in it, half-open ([ulo, uhi) x [vlo, vhi), the boundary rule's own sides), so that a query a
  // small step from the last one skips the descent. They hold for the tree, and the edit of it,
  // whose stamp they carry: a cursor taken to another tree, or kept across an edit, descends
  // afresh. A default cursor matches nothing. One per moving object; not to be shared between
  // threads.
  struct Cursor {
    Node leaf{0, 0};
    Box2 box;
    std::uint64_t stamp = 0;  // the tree's stamp_ when leaf and box were found (0: none)
    // A walk's lookahead (lookAhead): its last point, and the next two leaves its steps lead to
    // (with their boxes, of this stamp).
    double lastU = NAN, lastV = NAN;
    static constexpr int kAhead = 2;
    Node next[kAhead]{};
    Box2 nextBox[kAhead];
    int nextCount = 0;
  };
  // leafNode(u, v), starting from the cursor when (u, v) is in its box, and updating it. The
  // answer is the same leaf as leafNode(u, v). Precondition: contains(u, v). On entering a leaf
  // on a walk's course, ahead(items) is handed the items of a leaf ahead, whose references
  // are in cache, to prefetch what the caller reads of them (see lookAhead).
  Node leafNode(double u, double v, Cursor& cursor) const {
    return leafNode(u, v, cursor, [](std::span<const std::uint32_t>) {});
  }
  template <class Ahead>
  Node leafNode(double u, double v, Cursor& cursor, const Ahead& ahead) const {
    const Box2& b = cursor.box;
    if (u >= b.ulo && u < b.uhi && v >= b.vlo && v < b.vhi && cursor.stamp == stamp_) [[likely]] {
      cursor.lastU = u, cursor.lastV = v;
      return cursor.leaf;
    }
    const bool sameTree = cursor.stamp == stamp_;
    Node nd;
    const Box2& n = cursor.nextBox[0];
    if (sameTree && cursor.nextCount > 0 && u >= n.ulo && u < n.uhi && v >= n.vlo && v < n.vhi) {
      // On the course the lookahead found: its next leaf, without a descent (the box is the
      // descent's own, so the points in it are the leaf's).
      nd = cursor.leaf = cursor.next[0];
      cursor.box = n;
    } else {
      nd = descend(u, v, cursor);
    }
    const Node ready = lookAhead(u, v, sameTree, cursor);
    if (leafSize(ready) != 0) ahead(leafRange(ready));
    cursor.lastU = u, cursor.lastV = v;
    return nd;
  }
  std::span<const std::uint32_t> leafRange(const Node& leaf) const {
    return {refs_.data() + leaf.first, leafSize(leaf)};
  }

  // Calls visit(items) for every leaf whose closed box meets the segment (u0, v0)-(u1, v1)
  // (boxes widened by a relative 1e-12, so rounding never drops one).
  template <class Visit>
  void forLeavesAlong(double u0, double v0, double u1, double v1, Visit&& visit) const {
    walkAlong(
        u0, v0, u1, v1, [](std::uint32_t, double, double) { return true; },
        [&](std::span<const std::uint32_t> items) {
          visit(items);
          return false;
        });
  }
  // The same walk, pruned and stoppable: enter(node, t0, t1) is asked before each node whose
  // padded box the segment meets, t0..t1 the piece of the segment (parameter 0 at (u0, v0), 1 at
  // (u1, v1)) inside that box (widened by the padding), and the node is skipped when it returns
  // false; visit(items) returns true to stop the walk. Nodes are numbered as nodes() does.
  template <class Enter, class Visit>
  void walkAlong(double u0, double v0, double u1, double v1, Enter&& enter, Visit&& visit) const;

  // Dynamic edits. insert adds item to every leaf whose box it overlaps; a leaf that then holds
  // more than Maxpoly items is split by the build's own rule (buildNode), so the tree stays as
  // the build would shape it locally. prepare(items) is called on every leaf that changed, as
  // markLeaves' visit (reorder, return the single-layer flag). remove takes the item out of
  // every leaf whose box it overlaps (the same predicate must be given as at insertion). A leaf's
  // old reference range is abandoned when it moves to the end of the array; compact() reclaims
  // the space, and runs by itself when more than half the references are abandoned.
  // Precondition: the item lies within box() (the owner rebuilds otherwise).
  template <class Overlaps, class Prepare>
  void insert(std::uint32_t item, Overlaps&& overlaps, Prepare&& prepare);
  template <class Overlaps>
  void remove(std::uint32_t item, Overlaps&& overlaps);
  void compact();

  // Lets the owner reorder each leaf's items and flag it single-layer: visit(items) may permute
  // the span and returns whether to set kSingleLayer. On `threads` threads (batch::inSlices: 0,
  // one per hardware thread) when visit may run on several leaves at once (each leaf's items are
  // its own): the same tree for any count.
  template <class Visit>
  void markLeaves(Visit&& visit, unsigned threads = 1) {
    batch::inSlices(nodes_.size(), threads, 1u << 14, [&](std::size_t lo, std::size_t hi) {
      for (std::size_t i = lo; i < hi; ++i) {
        Node& n = nodes_[i];
        if (n.count == kInner) continue;
        const std::span<std::uint32_t> items(refs_.data() + n.first, leafSize(n));
        n.count = leafSize(n) | (visit(items) ? kSingleLayer : 0u);
      }
    });
    buildJumpTable();  // the table holds copies of the leaves
  }

  std::span<const Node> nodes() const { return nodes_; }
  // Calls visit(leaf, depth) for every leaf (the root at depth 0).
  template <class Visit>
  void forEachLeaf(Visit&& visit) const {
    if (nodes_.empty()) return;
    struct Item {
      std::uint32_t node, depth;
    };
    std::vector<Item> stack{{0, 0}};
    while (!stack.empty()) {
      const Item it = stack.back();
      stack.pop_back();
      const Node& nd = nodes_[it.node];
      if (nd.count != kInner) {
        visit(nd, it.depth);
        continue;
      }
      for (std::uint32_t c = 0; c < 4; ++c) stack.push_back({nd.first + c, it.depth + 1});
    }
  }
  // The jump table's depth (its 4^depth cells hold copies of the nodes there), 0 for none.
  std::uint32_t jumpDepth() const { return jumpDepth_; }
  std::span<const std::uint32_t> references() const { return refs_; }
  QuadtreeStats stats() const;

 private:
  friend struct TreeFileAccess;  // the on-disk format (treefile.hpp)
  struct Half {
    double u, v;
  };
  // The column (or row) at jumpDepth_ that the descent would reach: the last cut at or below x.
  // The cuts are the descent's own sums, so the answer is the same bit for bit; the estimate
  // from the scale is off by at most one column, and only at cut lines.
  static std::uint32_t jumpColumn(double x, const std::vector<double>& cut, double scale, double lo) {
    const auto last = static_cast<std::int64_t>(cut.size()) - 1;
    auto g = static_cast<std::int64_t>((x - lo) * scale);
    g = g < 0 ? 0 : g > last ? last : g;
    while (g > 0 && x < cut[g]) --g;
    while (g < last && x >= cut[g + 1]) ++g;
    return static_cast<std::uint32_t>(g);
  }
  // leafNode's descent, the leaf's box with it (a cursor's: also its leaf and this tree's stamp).
  Node descend(double u, double v, Box2& box) const;
  Node descend(double u, double v, Cursor& cursor) const;
  // A walk of steps smaller than its leaves (a vehicle, a profile, a scan line) that has just
  // entered the cursor's leaf will next cross the leaves its steps lead to. The one after next
  // has its references fetched now, and the next one, whose references were fetched a leaf ago,
  // is handed to the index (leafNode's `ahead`) to prefetch its items: a leaf's misses are waited for
  // while the walk crosses the two before it. The answers are the same; only the cache differs.
  // (sameTree: the cursor's lookahead is of this tree and edit.) Returns that next leaf (an empty
  // one for none).
  Node lookAhead(double u, double v, bool sameTree, Cursor& cursor) const;
  // The leaf (and its box) holding the first point p + k (du, dv), k = 1, 2, ..., past box
  // b, for a point p in or before b; false when that is over 64 steps on or off the tree.
  bool leafPast(const Box2& b, double u, double v, double du, double dv, Node& leaf, Box2& box) const;
  // A fresh value for every tree and every change of one (cursors compare it).
  std::uint64_t stamp_ = nextSerial();
  bool fetchAhead_ = false;  // lookAhead pays (the tree is larger than a cache holds)
  // Copies node n (at depth, with box) into the jump table cells it covers (if it is at or above
  // the table's depth).
  void refreshJump(std::uint32_t n, std::uint32_t depth, const Box2& box);
  template <class Visit>
  void forOverlappingLeaves(const Visit& visitLeaf, const std::function<bool(const Box2&)>& meets);
  void buildJumpTable();
  template <class Overlaps>
  void buildNode(std::uint32_t node, const Box2& box, std::uint32_t depth, std::vector<std::uint32_t>& items,
                 Overlaps& overlaps);
  // buildNode's own step: node becomes a leaf of items (false), or an inner node whose four
  // children are allocated, with their boxes and items in child and sub (true).
  template <class Overlaps>
  bool splitNode(std::uint32_t node, const Box2& box, std::uint32_t depth, std::vector<std::uint32_t>& items,
                 Overlaps& overlaps, Box2 (&child)[4], std::vector<std::uint32_t> (&sub)[4]);
  // The root split as buildNode splits it, then each child's subtree built apart on threads and
  // appended in child order, as the recursion lays them out.
  template <class Overlaps>
  void buildFromTheRootInParallel(const Box2& root, std::vector<std::uint32_t>& items, Overlaps& overlaps,
                                  unsigned threads);
  [[noreturn]] void tooManyReferences() const;
  // buildNode's lists of the children's items, one set a depth, kept from node to node while
  // a build runs (lists_ never moves under a recursion: sized to Maxdepth first).
  struct ChildLists {
    std::vector<std::uint32_t> sub[4];
  };
  std::vector<ChildLists> lists_;

  Box2 root_;
  QuadtreeOptions options_;
  std::vector<Half> half_;  // half the node size at each depth: the offset of the cut
  // Stored cuts (cost model), per node (meaningful for inner nodes); empty for midpoint cuts.
  BigVector<Point2> cut_;
  std::function<Box2(std::uint32_t)> boxOf_;  // during a cost-model build only
  // The cut of node n (at depth, box starting at lo): stored, or the midpoint as the descent
  // sums it.
  Point2 cutOf(std::uint32_t n, std::uint32_t depth, double lou, double lov) const {
    return cut_.empty() ? Point2{lou + half_[depth].u, lov + half_[depth].v} : cut_[n];
  }
  Point2 costCut(const Box2& box, std::uint32_t depth, std::span<const std::uint32_t> items) const;
  // Called every million nodes a build adds: a tree can outgrow its memory estimate (slivers,
  // stacks), so stop with an error while some memory is left instead of meeting the OOM killer.
  void checkMemoryLeft() const;
  BigVector<Node> nodes_;
  BigVector<std::uint32_t> refs_;
  // Jump table: for each cell of the uniform grid at depth jumpDepth_, a copy of the node at that
  // depth (or of the shallower leaf) covering it. 0 = no table. cutU_[i] is the low edge of column i as the
  // descent computes it.
  std::uint32_t jumpDepth_ = 0;
  double jumpScaleU_ = 0, jumpScaleV_ = 0;
  std::vector<double> cutU_, cutV_;
  BigVector<Node> jump_;
  std::uint64_t refBudget_ = 0;
  std::uint64_t abandoned_ = 0;  // references left behind by edits (see compact)
  std::uint32_t itemCount_ = 0;
  double minSizeU_ = 0, minSizeV_ = 0;
  std::uint32_t memoryCheckShift_ = 20;  // the build checks the memory left every 2^this nodes
};

template <class Enter, class Visit>
void Quadtree::walkAlong(double u0, double v0, double u1, double v1, Enter&& enter, Visit&& visit) const {
  if (half_.empty()) return;
  struct Item {
    std::uint32_t node, depth;
    double lu, lv, hu, hv;
  };
  const double du = u1 - u0, dv = v1 - v0;
  const double pad = 1e-12 * (std::fabs(root_.uhi - root_.ulo) + std::fabs(root_.vhi - root_.vlo));
  // Slab test of the segment against a closed, padded box; t0..t1 the piece inside.
  double t0 = 0, t1 = 1;
  auto meets = [&](double lu, double lv, double hu, double hv) {
    t0 = 0, t1 = 1;
    auto axis = [&](double o, double d, double lo, double hi) {
      lo -= pad, hi += pad;
      if (d == 0) return o >= lo && o <= hi;
      double a = (lo - o) / d, b = (hi - o) / d;
      if (a > b) std::swap(a, b);
      t0 = std::max(t0, a), t1 = std::min(t1, b);
      return t0 <= t1;
    };
    return axis(u0, du, lu, hu) && axis(v0, dv, lv, hv);
  };
  std::vector<Item> stack{{0, 0, root_.ulo, root_.vlo, root_.uhi, root_.vhi}};
  while (!stack.empty()) {
    const Item it = stack.back();
    stack.pop_back();
    if (!meets(it.lu, it.lv, it.hu, it.hv) || !enter(it.node, t0, t1)) continue;
    const Node& nd = nodes_[it.node];
    if (nd.count != kInner) {
      if (visit(leafRange(nd))) return;
      continue;
    }
    const Point2 cut = cutOf(it.node, it.depth, it.lu, it.lv);
    const double mu = cut.u, mv = cut.v;
    // Front to back along the segment (the child it starts in popped first), so that a walk
    // that stops at the first item it meets tends to meet the nearest.
    const Item child[4] = {{nd.first, it.depth + 1, it.lu, it.lv, mu, mv},
                           {nd.first + 1, it.depth + 1, mu, it.lv, it.hu, mv},
                           {nd.first + 2, it.depth + 1, it.lu, mv, mu, it.hv},
                           {nd.first + 3, it.depth + 1, mu, mv, it.hu, it.hv}};
    const unsigned start = (du < 0 ? 1u : 0u) | (dv < 0 ? 2u : 0u);
    for (const unsigned k : {3u, 1u, 2u, 0u}) stack.push_back(child[start ^ k]);
  }
}

template <class Visit>
void Quadtree::forOverlappingLeaves(const Visit& visitLeaf, const std::function<bool(const Box2&)>& meets) {
  struct Item {
    std::uint32_t node, depth;
    Box2 box;
  };
  std::vector<Item> stack{{0, 0, root_}};
  while (!stack.empty()) {
    const Item it = stack.back();
    stack.pop_back();
    if (!meets(it.box)) continue;
    const Node nd = nodes_[it.node];
    if (nd.count != kInner) {
      visitLeaf(it.node, it.depth, it.box);
      continue;
    }
    const Box2& b = it.box;
    const Point2 cut = cutOf(it.node, it.depth, b.ulo, b.vlo);
    const double mu = cut.u, mv = cut.v;
    stack.push_back({nd.first, it.depth + 1, {b.ulo, b.vlo, mu, mv}});
    stack.push_back({nd.first + 1, it.depth + 1, {mu, b.vlo, b.uhi, mv}});
    stack.push_back({nd.first + 2, it.depth + 1, {b.ulo, mv, mu, b.vhi}});
    stack.push_back({nd.first + 3, it.depth + 1, {mu, mv, b.uhi, b.vhi}});
  }
}

template <class Overlaps, class Prepare>
void Quadtree::insert(std::uint32_t item, Overlaps&& overlaps, Prepare&& prepare) {
  if (nodes_.empty() || half_.empty()) throw Error("quadtree: insert into a tree never built");
  stamp_ = nextSerial();
  itemCount_ = std::max(itemCount_, item + 1);
  refBudget_ = std::max<std::uint64_t>(refBudget_, 64ull * itemCount_ + (1ull << 22));
  forOverlappingLeaves(
      [&](std::uint32_t n, std::uint32_t depth, const Box2& box) {
        const Node old = nodes_[n];
        std::vector<std::uint32_t> items(refs_.begin() + old.first, refs_.begin() + old.first + leafSize(old));
        items.push_back(item);
        abandoned_ += leafSize(old);
        const std::size_t before = nodes_.size();
        buildNode(n, box, depth, items, overlaps);  // appends the leaf (or its subtree)
        auto mark = [&](std::uint32_t k) {
          Node& leaf = nodes_[k];
          if (leaf.count == kInner) return;
          const std::span<std::uint32_t> range(refs_.data() + leaf.first, leafSize(leaf));
          leaf.count = leafSize(leaf) | (prepare(range) ? kSingleLayer : 0u);
        };
        mark(n);
        for (std::size_t k = before; k < nodes_.size(); ++k) mark(static_cast<std::uint32_t>(k));
        refreshJump(n, depth, box);
      },
      [&](const Box2& b) { return overlaps(item, b); });
  if (abandoned_ > refs_.size() / 2 + 1024) compact();
}

template <class Overlaps>
void Quadtree::remove(std::uint32_t item, Overlaps&& overlaps) {
  if (nodes_.empty() || half_.empty()) return;
  stamp_ = nextSerial();
  forOverlappingLeaves(
      [&](std::uint32_t n, std::uint32_t depth, const Box2& box) {
        Node& leaf = nodes_[n];
        auto* begin = refs_.data() + leaf.first;
        auto* end = begin + leafSize(leaf);
        auto* at = std::find(begin, end, item);
        if (at == end) return;
        std::copy(at + 1, end, at);  // keeps the leaf's order; single-layer stays true
        leaf.count = (leafSize(leaf) - 1) | (leaf.count & kSingleLayer);
        ++abandoned_;
        refreshJump(n, depth, box);
      },
      [&](const Box2& b) { return overlaps(item, b); });
}

template <class Overlaps>
void Quadtree::build(std::uint32_t itemCount, Box2 root, const QuadtreeOptions& options, Overlaps&& overlaps,
                     double minSizeU, double minSizeV, const std::function<Box2(std::uint32_t)>& boxOf,
                     unsigned threads) {
  // A root much longer than it is wide would cut its short side into cells far thinner than the
  // items, each item referenced by thousands of them (a raster two pixels by five thousand). So
  // the short side is widened, about its centre, to at least half the long one.
  if (!root.empty()) {
    const double su0 = root.uhi - root.ulo, sv0 = root.vhi - root.vlo;
    const auto widen = [](double& lo, double& hi, double size) {
      const double mid = 0.5 * lo + 0.5 * hi;
      lo = std::min(lo, mid - 0.5 * size), hi = std::max(hi, mid + 0.5 * size);
    };
    if (su0 < 0.5 * sv0) widen(root.ulo, root.uhi, 0.5 * sv0);
    if (sv0 < 0.5 * su0) widen(root.vlo, root.vhi, 0.5 * su0);
  }
  root_ = root;
  cut_.clear();
  boxOf_ = options.cuts == QuadtreeOptions::Cuts::CostModel ? boxOf : nullptr;
  options_ = options;
  minSizeU_ = minSizeU;
  minSizeV_ = minSizeV;
  nodes_.assign(1, Node{0, 0});
  refs_.clear();
  half_.clear();
  jumpDepth_ = 0;
  cutU_.clear(), cutV_.clear(), jump_.clear();
  if (root.empty() || itemCount == 0) return;
  // Exact halvings of the root size (powers of two scale without rounding).
  const double su = root.uhi - root.ulo, sv = root.vhi - root.vlo;
  for (std::uint32_t d = 0; d <= options.maxDepth; ++d) {
    half_.push_back({std::ldexp(su, -static_cast<int>(d) - 1), std::ldexp(sv, -static_cast<int>(d) - 1)});
  }
  // Items that share an edge can never be separated by a cut, so with a Maxpoly below the number
  // of polygons along an edge or around a vertex every leaf on that edge would split down to
  // Maxdepth: a tree exponential in Maxdepth. Far before that, stop with an error that says what
  // to change.
  refBudget_ = 64ull * itemCount + (1ull << 22);
  itemCount_ = itemCount;
  std::vector<std::uint32_t> items(itemCount);
  for (std::uint32_t i = 0; i < itemCount; ++i) items[i] = i;
  if (boxOf_) cut_.assign(1, Point2{});
  // (A parallel build pays from about this many items: below, the threads cost more than they
  // save.)
  constexpr std::uint32_t kParallelItems = 1u << 15;
  if (threads != 1 && !boxOf_ && itemCount >= kParallelItems) {
    buildFromTheRootInParallel(root, items, overlaps, threads);
  } else {
    buildNode(0, root, 0, items, overlaps);
  }
  boxOf_ = nullptr;
  std::vector<ChildLists>().swap(lists_);
  nodes_.shrink_to_fit();
  cut_.shrink_to_fit();
  refs_.shrink_to_fit();
  buildJumpTable();
}

template <class Overlaps>
void Quadtree::buildNode(std::uint32_t node, const Box2& box, std::uint32_t depth, std::vector<std::uint32_t>& items,
                         Overlaps& overlaps) {
  Box2 child[4];
  // The children's lists in this depth's scratch lists: a node's subtree is built before its
  // next sibling's, so they are free again by then, and no node allocates its own.
  // (Sized on the first call for every depth a build can reach: never again under a `sub` of a
  // shallower call, whatever an earlier build or insert left.)
  const std::size_t depths = std::max<std::size_t>(depth + 1, std::size_t{options_.maxDepth} + 1);
  if (lists_.size() < depths) lists_.resize(depths);
  std::vector<std::uint32_t>(&sub)[4] = lists_[depth].sub;
  if (!splitNode(node, box, depth, items, overlaps, child, sub)) return;
  const std::uint32_t first = nodes_[node].first;
  for (int c = 0; c < 4; ++c) buildNode(first + c, child[c], depth + 1, sub[c], overlaps);
}

template <class Overlaps>
bool Quadtree::splitNode(std::uint32_t node, const Box2& box, std::uint32_t depth, std::vector<std::uint32_t>& items,
                         Overlaps& overlaps, Box2 (&child)[4], std::vector<std::uint32_t> (&sub)[4]) {
  if (items.size() <= options_.maxPoly || depth >= options_.maxDepth ||
      (box.uhi - box.ulo < minSizeU_ && box.vhi - box.vlo < minSizeV_)) {
    nodes_[node] = {static_cast<std::uint32_t>(refs_.size()), static_cast<std::uint32_t>(items.size())};
    refs_.insert(refs_.end(), items.begin(), items.end());
    return false;
  }
  const auto first = static_cast<std::uint32_t>(nodes_.size());
  nodes_[node] = {first, kInner};
  nodes_.resize(first + 4, Node{0, 0});
  // The same expressions as the descent: lo + half[depth] for midpoint cuts; stored cuts are
  // chosen by the cost model (or, for an edit's split, at the midpoint) and kept.
  Point2 cut = cutOf(node, depth, box.ulo, box.vlo);
  if (!cut_.empty()) {
    cut = boxOf_ ? costCut(box, depth, items) : Point2{box.ulo + half_[depth].u, box.vlo + half_[depth].v};
    cut_.resize(nodes_.size());
    cut_[node] = cut;
  }
  const double mu = cut.u, mv = cut.v;
  child[0] = {box.ulo, box.vlo, mu, mv}, child[1] = {mu, box.vlo, box.uhi, mv};
  child[2] = {box.ulo, mv, mu, box.vhi}, child[3] = {mu, mv, box.uhi, box.vhi};
  for (int c = 0; c < 4; ++c) {
    sub[c].clear();
    sub[c].reserve(items.size() / 2);
  }
  // Item by item (each item's data read once for its four children), in the items' order.
  for (std::uint32_t it : items) {
    for (int c = 0; c < 4; ++c) {
      if (overlaps(it, child[c])) sub[c].push_back(it);
    }
  }
  // A split pays only when a query that lands on terrain tests clearly fewer polygons in a child
  // than in the parent: the mean over the children that hold any polygon, as queries go where the
  // terrain is (a child left empty is free to answer, but it does not make the others cheaper).
  // It does not where polygons cannot be separated: a fan around a vertex, a stack of
  // overlapping polygons, the rim of such a stack, or slivers far thinner than the node along
  // one axis (a cut across them copies them all into both halves, down to Maxdepth). Such a node
  // stays a leaf. A split that copies nothing (every polygon in one child) always goes on: it
  // costs four nodes and leads to the cuts that separate.
  const std::size_t childRefs = sub[0].size() + sub[1].size() + sub[2].size() + sub[3].size();
  const int filled = !sub[0].empty() + !sub[1].empty() + !sub[2].empty() + !sub[3].empty();
  if (childRefs > items.size() &&
      static_cast<double>(childRefs) > kMinSplitGain * filled * static_cast<double>(items.size())) {
    nodes_.resize(first);
    if (!cut_.empty()) cut_.resize(first);
    nodes_[node] = {static_cast<std::uint32_t>(refs_.size()), static_cast<std::uint32_t>(items.size())};
    refs_.insert(refs_.end(), items.begin(), items.end());
    return false;
  }
  if (refs_.size() + items.size() > refBudget_ || nodes_.size() > refBudget_) tooManyReferences();
  if ((first >> memoryCheckShift_) != ((first + 4) >> memoryCheckShift_)) checkMemoryLeft();
  if (depth == 0) std::vector<std::uint32_t>().swap(items);  // free the root's list (all items) before descending
  return true;
}

template <class Overlaps>
void Quadtree::buildFromTheRootInParallel(const Box2& root, std::vector<std::uint32_t>& items, Overlaps& overlaps,
                                          unsigned threads) {
  Box2 child[4];
  std::vector<std::uint32_t> sub[4];
  if (!splitNode(0, root, 0, items, overlaps, child, sub)) return;
  // Each subtree in a tree of its own, its node 0 the child: the recursion's steps on its part,
  // with the whole tree's options and budget.
  Quadtree part[4];
  for (Quadtree& q : part) {
    q.root_ = root_, q.options_ = options_, q.half_ = half_;
    q.minSizeU_ = minSizeU_, q.minSizeV_ = minSizeV_;
    q.refBudget_ = refBudget_, q.itemCount_ = itemCount_;
    q.nodes_.assign(1, Node{0, 0});
  }
  // A part checks the memory left four times as often as a whole tree would (it sees a quarter
  // of the nodes), and its error stops the build on this thread, the first part's first.
  std::exception_ptr failed[4];
  for (Quadtree& q : part) q.memoryCheckShift_ = memoryCheckShift_ - 2;
  batch::inSlices(4, threads, 1, [&](std::size_t lo, std::size_t hi) {
    for (std::size_t c = lo; c < hi; ++c) {
      try {
        part[c].buildNode(0, child[c], 1, sub[c], overlaps);
      } catch (...) {
        failed[c] = std::current_exception();
      }
    }
  });
  for (const std::exception_ptr& e : failed) {
    if (e) std::rethrow_exception(e);
  }
  // The recursion's layout: child c at node 1 + c, then the subtrees below the children one after
  // another (child 0's first), their leaves' references likewise.
  for (int c = 0; c < 4; ++c) {
    const auto base = static_cast<std::uint32_t>(nodes_.size());
    const auto refBase = static_cast<std::uint32_t>(refs_.size());
    if (std::uint64_t{base} + part[c].nodes_.size() > refBudget_ || refs_.size() + part[c].refs_.size() > refBudget_) {
      tooManyReferences();
    }
    const auto placed = [&](Node n) {
      if (n.count == kInner) {
        n.first = n.first - 1 + base;
      } else {
        n.first += refBase;
      }
      return n;
    };
    nodes_[1 + c] = placed(part[c].nodes_[0]);
    for (std::size_t k = 1; k < part[c].nodes_.size(); ++k) nodes_.push_back(placed(part[c].nodes_[k]));
    refs_.insert(refs_.end(), part[c].refs_.begin(), part[c].refs_.end());
    BigVector<Node>().swap(part[c].nodes_);
    BigVector<std::uint32_t>().swap(part[c].refs_);
  }
}

}  // namespace qota
