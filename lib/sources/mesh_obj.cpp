// Wavefront OBJ, in double precision: qota's own reader (see the precision note in
// qota/mesh_io.hpp).

#include <Eigen/Core>
#include <cctype>
#include <charconv>
#include <cmath>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

#include "mesh_readers.hpp"
#include "qota/error.hpp"

namespace qota::detail {
namespace {

std::string_view trim(std::string_view s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.front()))) s.remove_prefix(1);
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.remove_suffix(1);
  return s;
}

std::vector<std::string_view> tokens(std::string_view s) {
  std::vector<std::string_view> out;
  std::size_t i = 0;
  while (i < s.size()) {
    while (i < s.size() && std::isspace(static_cast<unsigned char>(s[i]))) ++i;
    const std::size_t b = i;
    while (i < s.size() && !std::isspace(static_cast<unsigned char>(s[i]))) ++i;
    if (i > b) out.push_back(s.substr(b, i - b));
  }
  return out;
}

class ObjReader {
 public:
  ObjReader(MeshFile& out, const MeshFileOptions& options) : out_(out), builder_(out, options) {}

  void read() {
    std::ifstream in(out_.path, std::ios::binary);
    if (!in) throw Error(out_.path + ": cannot open for reading");
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (in.bad()) throw Error(out_.path + ": read error");

    std::uint64_t lineNo = 0;
    std::size_t pos = 0;
    std::string joined;  // a statement continued over lines with a trailing backslash
    std::uint64_t statementLine = 0;
    while (pos < text.size()) {
      std::size_t end = text.find('\n', pos);
      if (end == std::string::npos) end = text.size();
      std::string_view line(text.data() + pos, end - pos);
      pos = end + 1;
      ++lineNo;
      if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
      if (joined.empty()) statementLine = lineNo;
      if (!line.empty() && line.back() == '\\') {
        joined.append(line.substr(0, line.size() - 1)).push_back(' ');
        continue;
      }
      if (!joined.empty()) {
        joined.append(line);
        statement(joined, statementLine);
        joined.clear();
      } else {
        statement(line, lineNo);
      }
    }
    if (!joined.empty()) statement(joined, statementLine);

    // Vertices in file order, repeats joined; then faces (positive indices may point forward).
    std::vector<std::uint32_t> id(raw_.size());
    for (std::size_t i = 0; i < raw_.size(); ++i) id[i] = builder_.vertex(raw_[i]);
    for (const Face& f : faces_) {
      std::vector<std::uint32_t> ring;
      ring.reserve(f.count);
      for (std::uint32_t k = 0; k < f.count; ++k) {
        const std::int64_t c = corners_[f.first + k];
        if (c >= static_cast<std::int64_t>(raw_.size())) {
          fail(f.line, "vertex index " + std::to_string(c + 1) + " is out of range: the file has " +
                           std::to_string(raw_.size()) + " vertices");
        }
        ring.push_back(id[static_cast<std::size_t>(c)]);
      }
      builder_.addFace({std::move(ring)}, f.material, f.object, f.line,
                       [&] { return out_.path + ":" + std::to_string(f.line); });
    }
    builder_.finish();
  }

 private:
  struct Face {
    std::uint64_t line;
    std::uint32_t material, object;
    std::size_t first;
    std::uint32_t count;
  };

  [[noreturn]] void fail(std::uint64_t line, const std::string& message) const {
    throw Error(out_.path + ":" + std::to_string(line) + ": " + message);
  }

  double number(std::string_view t, std::uint64_t line) const {
    std::string_view s = t;
    if (s.size() > 1 && s[0] == '+') s.remove_prefix(1);  // from_chars does not take a '+'
    double d = 0;
    const auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), d);
    if (ec != std::errc() || p != s.data() + s.size()) {
      fail(line, "'" + std::string(t) + "' is not a number");
    }
    if (!std::isfinite(d)) fail(line, "'" + std::string(t) + "' is not a finite number");
    return d;
  }

  // One corner "v", "v/vt", "v/vt/vn" or "v//vn": the vertex index, 0-based (may be past the
  // vertices read so far; checked at the end). Texture and normal indices must be integers.
  std::int64_t corner(std::string_view t, std::uint64_t line) const {
    std::int64_t index[3] = {0, 0, 0};
    std::size_t part = 0, start = 0;
    for (std::size_t i = 0; i <= t.size(); ++i) {
      if (i < t.size() && t[i] != '/') continue;
      const std::string_view s = t.substr(start, i - start);
      if (part >= 3) fail(line, "face corner '" + std::string(t) + "' has more than three parts");
      if (!(s.empty() && part > 0)) {
        std::int64_t value = 0;
        const auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), value);
        if (ec != std::errc() || p != s.data() + s.size() || s.empty()) {
          fail(line, "face corner '" + std::string(t) + "': '" + std::string(s) + "' is not an integer index");
        }
        index[part] = value;
      }
      ++part;
      start = i + 1;
    }
    const std::int64_t k = index[0];
    if (k == 0) fail(line, "face corner '" + std::string(t) + "': index 0 (OBJ counts from 1)");
    if (k > 0) return k - 1;
    // Negative: relative to the vertices read so far (-1 is the last one).
    const std::int64_t r = static_cast<std::int64_t>(raw_.size()) + k;
    if (r < 0) {
      fail(line, "vertex index " + std::to_string(k) + " is out of range: only " + std::to_string(raw_.size()) +
                     " vertices so far");
    }
    return r;
  }

  void statement(std::string_view line, std::uint64_t lineNo) {
    if (const std::size_t hash = line.find('#'); hash != std::string_view::npos) line = line.substr(0, hash);
    line = trim(line);
    if (line.empty()) return;
    const std::size_t sp = std::min(line.size(), line.find_first_of(" \t"));
    const std::string_view key = line.substr(0, sp);
    const std::string_view rest = trim(line.substr(sp));

    if (key == "v") {
      const auto t = tokens(rest);
      if (t.size() < 3) {
        fail(lineNo, "a vertex needs three coordinates x y z, this one has " + std::to_string(t.size()));
      }
      // A w or vertex colour may follow; they must be numbers too but are not used.
      for (std::size_t i = 3; i < t.size(); ++i) number(t[i], lineNo);
      raw_.emplace_back(number(t[0], lineNo), number(t[1], lineNo), number(t[2], lineNo));
    } else if (key == "f" || key == "fo") {
      const auto t = tokens(rest);
      if (t.size() < 3) {
        fail(lineNo, "a face needs at least three corners, this one has " + std::to_string(t.size()));
      }
      if (t.size() > std::numeric_limits<std::uint32_t>::max()) fail(lineNo, "face too large");
      // Faces before any usemtl / o / g get the name "", made here so that it exists only when
      // such faces do.
      if (material_ == kUnset) material_ = builder_.material("");
      if (object_ == kUnset) object_ = builder_.object("");
      Face f{lineNo, material_, object_, corners_.size(), static_cast<std::uint32_t>(t.size())};
      for (const auto& c : t) corners_.push_back(corner(c, lineNo));
      faces_.push_back(f);
    } else if (key == "usemtl") {
      material_ = builder_.material(std::string(rest));
    } else if (key == "o" || key == "g") {
      object_ = builder_.object(std::string(rest));
    }
    // Everything else carries no polygon: texture coordinates and normals (vt, vn, vp), points
    // and lines (p, l), smoothing groups, material libraries, free-form curve statements, and
    // exporters' own extensions. They are skipped, as other readers do.
  }

  MeshFile& out_;
  Builder builder_;
  std::vector<Eigen::Vector3d> raw_;
  std::vector<Face> faces_;
  std::vector<std::int64_t> corners_;
  std::uint32_t material_ = kUnset, object_ = kUnset;
  static constexpr std::uint32_t kUnset = 0xffffffffu;
};

}  // namespace

void readObj(MeshFile& out, const MeshFileOptions& options) {
  ObjReader reader(out, options);
  reader.read();
}

}  // namespace qota::detail
