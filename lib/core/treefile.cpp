#include "qota/treefile.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <tuple>
#include <vector>

#include "qota/any_mapping.hpp"
#include "qota/atomic_file.hpp"
#include "qota/error.hpp"

namespace qota {
namespace {

constexpr char kMagic[8] = {'Q', 'O', 'T', 'A', 'T', 'R', 'E', 'E'};
// 2: the grid keeps no plane table; 3: band and unit; 4: height reference; 5: the planar triangle
// records are 64 bytes (a version 3 or 4 file's 128-byte records are remade from its corners).
constexpr std::uint32_t kVersion = 5;
constexpr std::uint32_t kOldestVersion = 3;       // version 2 stored its statistics with padding
constexpr std::uint32_t kOldTriangleBytes = 128;  // a planar triangle record before version 5
// Structs written as they are must have no padding, whose bytes would be whatever memory held:
// the same index must always make the same file.
static_assert(sizeof(QuadtreeOptions) == 12 && sizeof(QuadtreeStats) == 64 && sizeof(Quadtree::Node) == 8);
static_assert(sizeof(IndexStats) == 6 * 8 + sizeof(Box2) + sizeof(QuadtreeStats) + 8);

// The payload checksum: 8-byte words folded with a multiply-xor step (a few GB/s), the tail
// bytes as one zero-padded word, the length last.
class Checksum {
 public:
  void add(const void* data, std::size_t n) {
    const auto* p = static_cast<const unsigned char*>(data);
    bytes_ += n;
    // Finish a partial word first.
    while (n > 0 && fill_ > 0) {
      word_ |= static_cast<std::uint64_t>(*p++) << (8 * fill_);
      --n;
      if (++fill_ == 8) fold(word_), word_ = 0, fill_ = 0;
    }
    for (; n >= 8; n -= 8, p += 8) {
      std::uint64_t w;
      std::memcpy(&w, p, 8);
      fold(w);
    }
    for (; n > 0; --n) word_ |= static_cast<std::uint64_t>(*p++) << (8 * fill_++);
  }
  std::uint64_t value() const {
    std::uint64_t h = h_;
    if (fill_) h = (h ^ word_) * 0x9e3779b97f4a7c15ull, h ^= h >> 29;
    h = (h ^ bytes_) * 0xbf58476d1ce4e5b9ull;
    return h ^ (h >> 31);
  }

 private:
  void fold(std::uint64_t w) {
    h_ = (h_ ^ w) * 0x9e3779b97f4a7c15ull;
    h_ ^= h_ >> 29;
  }
  std::uint64_t h_ = 0x243f6a8885a308d3ull, word_ = 0, bytes_ = 0;
  int fill_ = 0;
};

// The payload, streamed straight to the file (no copy of a tree in memory: a tree file is as
// large as the index), summed on the way.
class Writer {
 public:
  explicit Writer(std::ostream& out) : out_(out) {}
  void raw(const void* p, std::size_t n) {
    out_.write(static_cast<const char*>(p), static_cast<std::streamsize>(n));
    sum_.add(p, n);
    bytes_ += n;
  }
  template <class T>
  void pod(const T& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    raw(&v, sizeof v);
  }
  void str(const std::string& s) {
    pod<std::uint64_t>(s.size());
    raw(s.data(), s.size());
  }
  template <class V>
  void array(const V& v) {
    using T = typename V::value_type;
    static_assert(std::is_trivially_copyable_v<T>);
    pod<std::uint64_t>(v.size());
    pod<std::uint32_t>(sizeof(T));
    raw(v.data(), v.size() * sizeof(T));
  }
  std::uint64_t bytes() const { return bytes_; }
  std::uint64_t checksum() const { return sum_.value(); }

 private:
  std::ostream& out_;
  Checksum sum_;
  std::uint64_t bytes_ = 0;
};

class Reader {
 public:
  Reader(std::ifstream& in, std::string path, std::uint64_t payload, std::uint32_t version)
      : in_(in), path_(std::move(path)), left_(payload), version_(version) {}
  std::uint32_t version() const { return version_; }
  [[noreturn]] void fail(const std::string& what) const {
    throw Error(path_ + ": not a valid qota tree file: " + what);
  }
  void raw(void* p, std::uint64_t n, const char* what) {
    if (n > left_) fail(std::string("truncated in ") + what);
    in_.read(static_cast<char*>(p), static_cast<std::streamsize>(n));
    if (!in_) fail(std::string("truncated in ") + what);
    sum_.add(p, n);
    left_ -= n;
  }
  template <class T>
  T pod(const char* what) {
    T v;
    raw(&v, sizeof v, what);
    return v;
  }
  std::string str(const char* what) {
    const auto n = pod<std::uint64_t>(what);
    if (n > left_) fail(std::string("truncated in ") + what);
    std::string s(n, '\0');
    raw(s.data(), n, what);
    return s;
  }
  template <class V>
  void array(V& v, const char* what) {
    using T = typename V::value_type;
    const auto n = pod<std::uint64_t>(what);
    const auto size = pod<std::uint32_t>(what);
    if (size != sizeof(T)) fail(std::string(what) + " has records of the wrong size");
    if (n > left_ / sizeof(T)) fail(std::string("truncated in ") + what);
    v.resize(n);
    raw(v.data(), n * sizeof(T), what);
  }
  // An array of records of an older layout, read (and summed) but not kept: their count.
  std::uint64_t skipArray(std::uint32_t recordSize, const char* what) {
    const auto n = pod<std::uint64_t>(what);
    const auto size = pod<std::uint32_t>(what);
    if (size != recordSize) fail(std::string(what) + " has records of the wrong size");
    if (n > left_ / size) fail(std::string("truncated in ") + what);
    std::vector<char> chunk(std::size_t{1} << 20);
    for (std::uint64_t rest = n * size; rest > 0;) {
      const std::uint64_t step = std::min<std::uint64_t>(rest, chunk.size());
      raw(chunk.data(), step, what);
      rest -= step;
    }
    return n;
  }
  std::uint64_t left() const { return left_; }
  std::uint64_t checksum() const { return sum_.value(); }

 private:
  std::ifstream& in_;
  std::string path_;
  std::uint64_t left_;
  std::uint32_t version_;
  Checksum sum_;
};

// A file's kind: its mapping's place in AnyMapping's list (any_mapping.hpp).
template <class Index>
std::uint32_t kindOf(const Index& index) {
  return static_cast<std::uint32_t>(AnyMapping(index.mapping()).index());
}

}  // namespace

// Reads and writes the private state of the indexes (a friend of each).
struct TreeFileAccess {
  static void write(Writer& w, const Quadtree& t) {
    w.pod(t.root_);
    w.pod(t.options_);
    w.pod(t.refBudget_);
    w.pod(t.itemCount_);
    w.pod(t.minSizeU_);
    w.pod(t.minSizeV_);
    w.array(t.half_);
    w.array(t.cut_);
    w.array(t.nodes_);
    w.array(t.refs_);
  }

  static void read(Reader& r, Quadtree& t) {
    t.root_ = r.pod<Box2>("quadtree box");
    t.options_ = r.pod<QuadtreeOptions>("quadtree options");
    t.refBudget_ = r.pod<std::uint64_t>("quadtree");
    t.itemCount_ = r.pod<std::uint32_t>("quadtree");
    t.minSizeU_ = r.pod<double>("quadtree");
    t.minSizeV_ = r.pod<double>("quadtree");
    r.array(t.half_, "quadtree cut sizes");
    r.array(t.cut_, "quadtree cuts");
    r.array(t.nodes_, "quadtree nodes");
    r.array(t.refs_, "quadtree references");
  }

  // Every index the descent and the leaves can follow is in range, children come after their
  // parent (so there is no cycle), and no leaf is deeper than the table of cut sizes.
  static void validate(const Reader& r, const Quadtree& t, std::uint64_t items) {
    if (t.nodes_.empty()) r.fail("the quadtree has no root");
    if (t.itemCount_ != items) r.fail("the quadtree indexes a different number of polygons");
    if (t.nodes_.size() > 1 || t.nodes_[0].count != 0) {
      if (t.root_.empty() || !std::isfinite(t.root_.ulo) || !std::isfinite(t.root_.uhi) ||
          !std::isfinite(t.root_.vlo) || !std::isfinite(t.root_.vhi)) {
        r.fail("the quadtree's box is empty or not finite");
      }
    }
    for (const auto& h : t.half_) {
      if (!std::isfinite(h.u) || !std::isfinite(h.v)) r.fail("a quadtree cut size is not finite");
    }
    // (A build keeps a cut size for every depth to Maxdepth; an insert splits down to it.)
    if (!t.half_.empty() && t.half_.size() != std::uint64_t{t.options_.maxDepth} + 1) {
      r.fail("the quadtree's Maxdepth does not match its table of cut sizes");
    }
    if (!t.cut_.empty() && t.cut_.size() != t.nodes_.size()) r.fail("the quadtree's cut table has the wrong size");
    for (const auto& c : t.cut_) {
      if (!std::isfinite(c.u) || !std::isfinite(c.v)) r.fail("a quadtree cut is not finite");
    }
    struct Item {
      std::uint64_t node, depth;
    };
    std::vector<Item> stack{{0, 0}};
    std::uint64_t seen = 0;
    while (!stack.empty()) {
      const Item it = stack.back();
      stack.pop_back();
      if (++seen > t.nodes_.size()) r.fail("the quadtree's nodes are shared or cyclic");
      const Quadtree::Node& n = t.nodes_[it.node];
      if (n.count == Quadtree::kInner) {
        if (it.depth + 1 >= t.half_.size()) r.fail("the quadtree is deeper than its cut table");
        if (n.first <= it.node || std::uint64_t{n.first} + 4 > t.nodes_.size()) {
          r.fail("a quadtree node points outside the node array");
        }
        for (std::uint32_t c = 0; c < 4; ++c) stack.push_back({n.first + c, it.depth + 1});
      } else {
        const std::uint64_t size = Quadtree::leafSize(n);
        if (std::uint64_t{n.first} + size > t.refs_.size()) r.fail("a leaf points outside the references");
        for (std::uint64_t i = 0; i < size; ++i) {
          if (t.refs_[n.first + i] >= items) r.fail("a leaf references a missing polygon");
        }
      }
    }
  }

  static void write(Writer& w, const PlanarCore& x) {
    x.stats();  // brings the tree statistics up to date after edits
    w.pod(x.hmin_);
    w.pod(x.hmax_);
    w.pod(x.umax_);
    w.pod(x.vmax_);
    w.pod(x.stats_);
    w.array(x.tris_);
    w.array(x.cold_);
    w.array(x.corners2_);
    w.array(x.cornerH_);
    w.array(x.ledger_.flags());
    w.pod(x.grid_.w);
    w.pod(x.grid_.h);
    w.pod(x.grid_.u0);
    w.pod(x.grid_.v0);
    w.pod(x.grid_.inv);
    w.array(x.grid_.cellTri);
    write(w, x.tree_);
  }

  static void read(Reader& r, PlanarCore& x) {
    x.hmin_ = r.pod<double>("heights");
    x.hmax_ = r.pod<double>("heights");
    x.umax_ = r.pod<double>("domain");
    x.vmax_ = r.pod<double>("domain");
    x.stats_ = r.pod<IndexStats>("statistics");
    if (r.version() >= 5) {
      r.array(x.tris_, "triangles");
    } else {
      x.tris_.resize(r.skipArray(kOldTriangleBytes, "triangles"));  // remade by derive, once the corners are checked
    }
    r.array(x.cold_, "triangle corners");
    r.array(x.corners2_, "vertices");
    r.array(x.cornerH_, "vertex heights");
    r.array(x.ledger_.flags(), "removed polygons");
    x.grid_.w = r.pod<std::uint32_t>("grid");
    x.grid_.h = r.pod<std::uint32_t>("grid");
    x.grid_.u0 = r.pod<double>("grid");
    x.grid_.v0 = r.pod<double>("grid");
    for (double& g : x.grid_.inv) g = r.pod<double>("grid");
    r.array(x.grid_.cellTri, "grid cells");
    read(r, x.tree_);
  }

  // What a valid file's arrays determine: the lean grid's tables, and an older file's records.
  static void derive(const Reader& r, PlanarCore& x) {
    if (r.version() < 5) {
      x.remakeRecords();
      x.stats_.memoryBytes -=
          x.tris_.size() * (kOldTriangleBytes - sizeof(PlanarCore::Tri));  // counted at the old size
    }
    if (x.grid_.on()) x.grid_.setUpLean(x.cold_, x.corners2_, x.cornerH_);
  }
  template <class M>
  static void derive(const Reader&, CurvedIndex<M>&) {}

  static void validate(const Reader& r, const PlanarCore& x) {
    if (x.grid_.on()) {
      if (x.grid_.w < 2 || x.grid_.h < 2 || x.grid_.cellTri.size() != 2ull * (x.grid_.w - 1) * (x.grid_.h - 1)) {
        r.fail("the grid's cell table has the wrong size");
      }
      for (std::uint32_t t : x.grid_.cellTri) {
        if (t != kNoTriangle && t >= x.tris_.size()) r.fail("a grid cell references a missing triangle");
      }
      for (double g : {x.grid_.u0, x.grid_.v0, x.grid_.inv[0], x.grid_.inv[1], x.grid_.inv[2], x.grid_.inv[3]}) {
        if (!std::isfinite(g)) r.fail("the grid's geometry is not finite");
      }
      if (std::uint64_t{x.grid_.w} * x.grid_.h != x.corners2_.size()) r.fail("the grid does not match its vertices");
    }
    if (x.cold_.size() != x.tris_.size()) r.fail("triangle tables differ in length");
    if (x.cornerH_.size() != x.corners2_.size()) r.fail("vertex tables differ in length");
    for (const auto& c : x.cold_) {
      for (std::uint32_t v : c.corner) {
        if (v >= x.corners2_.size()) r.fail("a triangle uses a missing vertex");
      }
    }
    validate(r, x.tree_, x.tris_.size());
  }

  template <class M>
  static void write(Writer& w, const CurvedIndex<M>& x) {
    x.stats();  // brings the tree statistics up to date after edits
    w.pod(x.scale_);
    w.pod(x.stats_);
    w.array(x.tris_);
    w.array(x.polarNorth_);
    w.array(x.polarSouth_);
    w.array(x.ledger_.flags());
    write(w, x.tree_);
  }

  template <class M>
  static void read(Reader& r, CurvedIndex<M>& x) {
    x.scale_ = r.pod<double>("scale");
    x.stats_ = r.pod<IndexStats>("statistics");
    r.array(x.tris_, "triangles");
    r.array(x.polarNorth_, "north polar list");
    r.array(x.polarSouth_, "south polar list");
    r.array(x.ledger_.flags(), "removed polygons");
    read(r, x.tree_);
  }

  template <class M>
  static void validate(const Reader& r, const CurvedIndex<M>& x) {
    for (const auto* list : {&x.polarNorth_, &x.polarSouth_}) {
      for (std::uint32_t i : *list) {
        if (i >= x.tris_.size()) r.fail("a polar list references a missing triangle");
      }
    }
    if (!std::isfinite(x.scale_)) r.fail("the scale is not finite");
    validate(r, x.tree_, x.tris_.size());
  }

  template <PlanarMapping M>
  static PlanarIndex<M> load(Reader& r, const M& mapping) {
    PlanarIndex<M> index(mapping);
    index.frame_ = mapping.frame();
    read(r, index);
    return index;
  }
  template <AxialMapping M>
  static CurvedIndex<M> load(Reader& r, const M& mapping) {
    CurvedIndex<M> index;
    index.mapping_ = mapping;
    read(r, index);
    return index;
  }

  static void rebuildJumpTable(Quadtree& t) { t.buildJumpTable(); }
  template <class I>
  static Quadtree& tree(I& index) {
    return index.tree_;
  }
};

bool isTreeFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  char magic[8] = {};
  return in.read(magic, 8) && std::memcmp(magic, kMagic, 8) == 0;
}

template <class Index>
void saveTree(const std::string& path, const Index& index, const TreeSource& source) {
  AtomicFile file(path);
  std::ofstream& out = file.stream();
  // The header, with the payload's size and checksum filled in once it is written.
  out.write(kMagic, 8);
  const std::uint32_t version = kVersion, kind = kindOf(index);
  out.write(reinterpret_cast<const char*>(&version), 4);
  out.write(reinterpret_cast<const char*>(&kind), 4);
  const std::uint64_t zero = 0;
  out.write(reinterpret_cast<const char*>(&zero), 8);
  out.write(reinterpret_cast<const char*>(&zero), 8);
  Writer w(out);
  w.str(index.mapping().describe());
  w.str(source.path);
  w.str(source.crsWkt);
  w.pod(source.width);
  w.pod(source.height);
  w.pod(source.geotransform);
  w.pod(source.band);
  w.str(source.verticalUnit);
  w.pod(source.metresPerUnit);
  w.str(source.heightRef);
  w.str(source.geoidGrid);
  TreeFileAccess::write(w, index);
  const std::uint64_t payload = w.bytes(), checksum = w.checksum();
  out.seekp(16);
  out.write(reinterpret_cast<const char*>(&payload), 8);
  out.write(reinterpret_cast<const char*>(&checksum), 8);
  file.commit();
}

// saveTree for every index of AnyIndex (a mapping added to the list has its tree files).
template <class... I>
constexpr auto savers(std::variant<I...>*) {
  return std::tuple{&saveTree<I>...};
}
[[maybe_unused]] const auto kSavers = savers(static_cast<AnyIndex*>(nullptr));

void saveTree(const std::string& path, const AnyIndex& index, const TreeSource& source) {
  std::visit([&](const auto& i) { saveTree(path, i, source); }, index);
}

TreeFile loadTree(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(path + ": cannot open");
  in.seekg(0, std::ios::end);
  const auto fileSize = static_cast<std::uint64_t>(in.tellg());
  in.seekg(0);
  char magic[8] = {};
  std::uint32_t version = 0, kind = 0;
  std::uint64_t payload = 0, checksum = 0;
  in.read(magic, 8);
  if (!in || std::memcmp(magic, kMagic, 8) != 0) {
    throw Error(path + ": not a qota tree file (no QOTATREE magic)");
  }
  in.read(reinterpret_cast<char*>(&version), 4);
  in.read(reinterpret_cast<char*>(&kind), 4);
  in.read(reinterpret_cast<char*>(&payload), 8);
  in.read(reinterpret_cast<char*>(&checksum), 8);
  if (!in) throw Error(path + ": not a valid qota tree file: truncated header");
  if (version < kOldestVersion || version > kVersion) {
    throw Error(path + ": tree file version " + std::to_string(version) + ", this qota reads " +
                std::to_string(kOldestVersion) + " to " + std::to_string(kVersion) +
                "; rebuild it from its source with qota build");
  }
  if (kind >= std::variant_size_v<AnyMapping>) {
    throw Error(path + ": not a valid qota tree file: unknown kind " + std::to_string(kind));
  }
  if (payload != fileSize - 32) {
    throw Error(path + ": not a valid qota tree file: truncated or extended (" + std::to_string(fileSize - 32) +
                " payload bytes, the header says " + std::to_string(payload) + ")");
  }
  Reader r(in, path, payload, version);
  AnyMapping mapping;
  try {
    mapping = parseMapping(r.str("mapping"));
  } catch (const Error& e) {
    r.fail(std::string("bad mapping: ") + e.what());
  }
  TreeSource source;
  source.path = r.str("source");
  source.crsWkt = r.str("source");
  source.width = r.pod<int>("source");
  source.height = r.pod<int>("source");
  source.geotransform = r.pod<std::array<double, 6>>("source");
  source.band = r.pod<int>("source");
  source.verticalUnit = r.str("source");
  source.metresPerUnit = r.pod<double>("source");
  if (version >= 4) {
    source.heightRef = r.str("source");
    source.geoidGrid = r.str("source");
  }
  if (!(source.metresPerUnit > 0) || !std::isfinite(source.metresPerUnit) || source.band < 1) {
    r.fail("bad source band or vertical unit");
  }
  if (mapping.index() != kind) r.fail("its mapping does not match its kind");
  TreeFile tf{std::visit([&](const auto& m) -> AnyIndex { return TreeFileAccess::load(r, m); }, mapping),
              std::move(source)};
  if (r.left() != 0) r.fail("unexpected bytes after the index");
  if (r.checksum() != checksum) r.fail("checksum mismatch (the file is damaged or was altered)");
  std::visit(
      [&](auto& index) {
        TreeFileAccess::validate(r, index);
        TreeFileAccess::derive(r, index);
        TreeFileAccess::rebuildJumpTable(TreeFileAccess::tree(index));
      },
      tf.index);
  return tf;
}

}  // namespace qota
