// qota sample's line loop (sample_lines.hpp): input read in large blocks, cut into lines, parsed,
// answered and formatted a batch at a time on every core, written in order.
#include "sample_lines.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <future>
#include <thread>
#include <vector>

#include "cancel.hpp"
#include "qota/error.hpp"
#include "text_output.hpp"

namespace qota::tools::sampling {
namespace {

// "'token' <what>", built by appending (GCC 12 warns falsely on "'" + std::string + "'"), with
// bytes a terminal would not show (control characters, a byte-order mark) written as escapes.
std::string quoted(std::string_view token, std::string_view what) {
  std::string m = "'";
  for (const char c : token) {
    const auto u = static_cast<unsigned char>(c);
    if (u >= 0x20 && u < 0x7f) {
      m += c;
    } else {
      static const char* hex = "0123456789ABCDEF";
      m += c == '\r'   ? std::string("\\r")
           : c == '\t' ? std::string("\\t")
                       : std::string{'\\', 'x', hex[u >> 4], hex[u & 15]};
    }
  }
  m += "' ";
  m += what;
  return m;
}

bool isSeparator(char c) { return c == ' ' || c == '\t' || c == ','; }

// One input line: its coordinates, and the fields after them, passed through to the output.
struct PointLine {
  double v[3] = {0, 0, 0};
  int count = 0;          // coordinates read: 0 for a blank line, else `want`
  std::string_view rest;  // the text after the coordinates and their separators
  char separator = ' ';   // what follows the last coordinate: ',', '\t' or ' '
};

// Reads the first `want` fields of a line as finite numbers (fields are separated by spaces,
// tabs or commas; a number may be in double quotes) and keeps the rest of the line as it is. Returns false, with the
// message in `problem`, for a bad line; true for a good (or blank) one, leaving `problem` as it is.
bool parsePointLine(std::string_view line, int want, PointLine& out, std::string& problem) {
  out = PointLine{};
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  std::size_t i = 0;
  while (i < line.size() && isSeparator(line[i])) ++i;
  if (i == line.size()) return true;  // blank
  for (int k = 0; k < want; ++k) {
    while (i < line.size() && isSeparator(line[i])) ++i;
    if (i == line.size()) {
      const char* expected = want == 3 ? "expected 'x y z' (--query-z)" : "expected 'x y'";
      problem = std::string(expected) + ", got " + std::to_string(k) + (k == 1 ? " value" : " values");
      return false;
    }
    // A number ends where its field does (no separator can be part of one); a quoted field (a
    // spreadsheet's CSV: "-121.76","46.85") holds the number between its quotes.
    const bool inQuotes = line[i] == '"';
    double v = 0;
    const auto r = std::from_chars(line.data() + i + inQuotes, line.data() + line.size(), v);
    std::size_t end = static_cast<std::size_t>(r.ptr - line.data());
    const bool closed = !inQuotes || (end < line.size() && line[end] == '"');
    end += inQuotes && closed;
    if (r.ec != std::errc() || !closed || (end < line.size() && !isSeparator(line[end]))) {
      std::size_t j = i;
      while (j < line.size() && !isSeparator(line[j])) ++j;
      const std::string_view token = line.substr(i, j - i);
      problem = quoted(token, "is not a number");
      return false;
    }
    if (!std::isfinite(v)) {
      problem = quoted(line.substr(i, end - i), "is not a finite number");
      return false;
    }
    out.v[k] = v;
    i = end;
  }
  out.count = want;
  if (i < line.size()) out.separator = line[i] == ',' || line[i] == '\t' ? line[i] : ' ';
  while (i < line.size() && isSeparator(line[i])) ++i;
  out.rest = line.substr(i);
  return true;
}

// Appends a number as formatNumber writes it, without a string per number.
void appendNumber(std::string& out, double value, int precision) {
  char buf[340 + kMaxPrecision];
  precision = std::min(precision, kMaxPrecision);
  const auto r = precision < 0 ? std::to_chars(buf, buf + sizeof buf, value)
                               : std::to_chars(buf, buf + sizeof buf, value, std::chars_format::fixed, precision);
  if (r.ec != std::errc()) throw Error("cannot format a number");
  out.append(buf, r.ptr);
}

// A line's outcome: its output text is written in order; a failure's message goes to stderr.
struct LineResult {
  std::string_view line;
  PointLine p;
  std::string problem;      // parse error, or the surface's
  std::string token;        // printed in place of the height when there is a problem
  std::uint32_t query = 0;  // its query's index when p.count > 0
};

// The cores a batch's lines are parsed and formatted on.
const std::size_t kThreads = std::max(1u, std::thread::hardware_concurrency());

// The line loop: input read in large blocks and cut into lines; each batch of lines parsed on
// both cores, transformed (--srs) and answered as one batch, formatted on both cores, written
// in order. The text of every line is as the line-by-line loop wrote it.
class LineLoop {
 public:
  LineLoop(const SampleOptions& options, const Surface& surface, OGRCoordinateTransformation* transform,
           std::ostream& output, std::ostream& err, std::string where, bool integerSource)
      : o_(options),
        surface_(surface),
        transform_(transform),
        out_(output),
        err_(err),
        where_(std::move(where)),
        roundNoise_(integerSource && options.precision < 0) {}

  // Reads `in` to its end. Returns whether any line failed.
  bool run(std::istream& in) {
    // The next block is read while this one's lines are answered: on another thread, so the
    // input must not flush the output it is tied to (std::cin to std::cout) meanwhile.
    std::ostream* const tied = in.tie(nullptr);
    struct Retie {
      std::istream& in;
      std::ostream* tied;
      ~Retie() { in.tie(tied); }
    } retie{in, tied};
    constexpr std::size_t kBlock = 1 << 22;
    const auto readBlock = [&in, this](std::string& raw) {  // true at the end of the input
      raw.resize(kBlock);
      in.read(raw.data(), static_cast<std::streamsize>(kBlock));
      raw.resize(static_cast<std::size_t>(in.gcount()));
      if (in.bad()) throw Error(where_ + ": read error");
      return !in;
    };
    std::string data, raw, ahead;  // data: the last block's unfinished line, then this block
    std::vector<std::string_view> lines;
    bool first = true, crOnly = false;
    for (bool end = readBlock(raw);;) {
      if (first) {
        // A UTF-8 byte-order mark is not part of the first line; a file whose lines end in a
        // carriage return alone (classic Mac OS) has no newline in its first block.
        if (raw.compare(0, 3, "\xEF\xBB\xBF") == 0) raw.erase(0, 3);
        crOnly = raw.find('\n') == std::string::npos && raw.find('\r') != std::string::npos;
        first = false;
      }
      if (crOnly) std::replace(raw.begin(), raw.end(), '\r', '\n');
      data.append(raw);
      std::future<bool> next;
      if (!end) next = std::async(std::launch::async, [&] { return readBlock(ahead); });
      const std::size_t start = splitLines(data, end, lines);
      constexpr std::size_t kBatch = 1 << 16;
      for (std::size_t b = 0; b < lines.size(); b += kBatch) {
        throwIfCancelled();
        batchOf(std::span<const std::string_view>(lines).subspan(b, std::min(kBatch, lines.size() - b)));
      }
      data.erase(0, start);
      if (end) break;
      end = next.get();
      raw.swap(ahead);
    }
    if (failures_ > kMostMessages) {
      err_ << "qota sample: " << where_ << ": " << failures_ - kMostMessages << " more failed lines (" << failures_
           << " in all; the first " << kMostMessages << " are named above)\n";
    }
    return failed_;
  }

 private:
  // Repeated per-line messages are capped (as GDAL caps its repeated errors): the first ones,
  // then a count.
  static constexpr std::uint64_t kMostMessages = 20;
  std::uint64_t failures_ = 0;
  // The complete lines of data (and its unfinished last one at the end of the input), found on
  // every core; returns where the unfinished line starts.
  static std::size_t splitLines(const std::string& data, bool end, std::vector<std::string_view>& lines) {
    const std::size_t slices = data.size() >= (1u << 20) ? kThreads : 1;
    std::vector<std::vector<std::size_t>> ends(slices);  // each slice's newlines
    const std::size_t each = (data.size() + slices - 1) / slices;
    inParallel(slices, 1, [&](std::size_t lo, std::size_t hi) {
      for (std::size_t s = lo; s < hi; ++s) {
        std::vector<std::size_t> found;  // (moved in at the end, as the format's text)
        const char* p = data.data() + std::min(data.size(), s * each);
        const char* stop = data.data() + std::min(data.size(), (s + 1) * each);
        while (const void* nl = std::memchr(p, '\n', static_cast<std::size_t>(stop - p))) {
          p = static_cast<const char*>(nl);
          found.push_back(static_cast<std::size_t>(p - data.data()));
          ++p;
        }
        ends[s] = std::move(found);
      }
    });
    lines.clear();
    std::size_t start = 0;
    for (const auto& e : ends) {
      for (const std::size_t nl : e) lines.emplace_back(data.data() + start, nl - start), start = nl + 1;
    }
    if (end && start < data.size()) {  // a last line without its newline
      lines.emplace_back(data.data() + start, data.size() - start);
      start = data.size();
    }
    return start;
  }

  void batchOf(std::span<const std::string_view> lines) {
    const std::size_t n = lines.size();
    const int want = o_.queryZ ? 3 : 2;
    results_.resize(n);
    const std::uint64_t first = lineNo_ + 1;
    lineNo_ += n;
    // Parse, and number the queries: both on every core, in the same slices (a slice's queries
    // follow the earlier slices').
    const std::size_t slices = std::max<std::size_t>(1, std::min<std::size_t>(kThreads, n / 2048));
    const std::size_t each = (n + slices - 1) / slices;
    std::vector<std::size_t> count(slices + 1, 0);
    inParallel(slices, 1, [&](std::size_t lo, std::size_t hi) {
      for (std::size_t s = lo; s < hi; ++s) {
        std::size_t queries = 0;  // (counted here: slices counting in `count` share its cache line)
        for (std::size_t i = s * each; i < std::min(n, (s + 1) * each); ++i) {
          LineResult& r = results_[i];  // reset field by field: the strings keep their buffers
          r.line = lines[i];
          r.p = PointLine{};
          r.problem.clear(), r.token.clear();
          r.query = 0;
          if (o_.header && first + i == 1) continue;  // (written as the header)
          if (!parsePointLine(lines[i], want, r.p, r.problem)) {
            r.token = "error";
            if (first + i == 1 && !o_.header) r.problem += " (a header line? --header skips it)";
          }
          queries += r.problem.empty() && r.p.count > 0;
        }
        count[s + 1] = queries;
      }
    });
    for (std::size_t s = 0; s < slices; ++s) count[s + 1] += count[s];
    // Queries, placed (--srs), answered.
    queries_.resize(count[slices]);
    answers_.resize(count[slices]);
    inParallel(slices, 1, [&](std::size_t lo, std::size_t hi) {
      for (std::size_t s = lo; s < hi; ++s) {
        std::size_t k = count[s];
        for (std::size_t i = s * each; i < std::min(n, (s + 1) * each); ++i) {
          LineResult& r = results_[i];
          if (!r.problem.empty() || r.p.count == 0) continue;
          r.query = static_cast<std::uint32_t>(k);
          Query& q = queries_[k];
          q.x = o_.swapXY ? r.p.v[1] : r.p.v[0], q.y = o_.swapXY ? r.p.v[0] : r.p.v[1], q.z = r.p.v[2];
          ++k;  // (its answer is set whole by the surface, or by the --srs failure below)
        }
      }
    });
    std::vector<std::uint8_t> placed(queries_.size(), 1);
    if (transform_ && !queries_.empty()) {
      std::vector<double> xs(queries_.size()), ys(queries_.size());
      std::vector<int> ok(queries_.size(), 0);
      for (std::size_t k = 0; k < queries_.size(); ++k) xs[k] = queries_[k].x, ys[k] = queries_[k].y;
      transform_->Transform(static_cast<int>(queries_.size()), xs.data(), ys.data(), nullptr, ok.data());
      for (std::size_t k = 0; k < queries_.size(); ++k) {
        if (ok[k] && std::isfinite(xs[k]) && std::isfinite(ys[k])) {
          queries_[k].x = xs[k], queries_[k].y = ys[k];
        } else {
          placed[k] = 0;
          answers_[k] = outside("error", "cannot transform (" + formatNumber(queries_[k].x) + ", " +
                                             formatNumber(queries_[k].y) + ") from " + o_.srs + " to the source's CRS");
        }
      }
    }
    answer(placed);
    // Format, on every core.
    std::vector<std::string> text(slices);
    inParallel(slices, 1, [&](std::size_t lo, std::size_t hi) {
      for (std::size_t s = lo; s < hi; ++s) {
        std::string t;  // (moved in at the end: the slices' strings share a cache line)
        t.reserve(each * 24);
        for (std::size_t i = s * each; i < std::min(n, (s + 1) * each); ++i) format(i, first + i, t);
        text[s] = std::move(t);
      }
    });
    for (std::size_t s = 0; s < slices; ++s) out_.write(text[s].data(), static_cast<std::streamsize>(text[s].size()));
    for (std::size_t i = 0; i < n; ++i) {
      if (results_[i].problem.empty()) continue;
      failed_ = true;
      if (++failures_ > kMostMessages) continue;  // (counted, and said once at the end)
      err_ << "qota sample: " << where_ << ':' << first + i << ": " << results_[i].problem << '\n';
    }
  }

  // The surface's answers for the placed queries, in one batch.
  void answer(const std::vector<std::uint8_t>& placed) {
    if (std::find(placed.begin(), placed.end(), 0) == placed.end()) {  // every one (no --srs failure)
      surface_(queries_, o_.queryZ, answers_);
      return;
    }
    std::vector<Query> q;
    std::vector<std::uint32_t> at;
    for (std::size_t k = 0; k < queries_.size(); ++k) {
      if (placed[k]) q.push_back(queries_[k]), at.push_back(static_cast<std::uint32_t>(k));
    }
    std::vector<Answer> a(q.size());
    surface_(q, o_.queryZ, a);
    for (std::size_t j = 0; j < q.size(); ++j) answers_[at[j]] = std::move(a[j]);
  }

  void format(std::size_t i, std::uint64_t lineNo, std::string& t) {
    LineResult& r = results_[i];
    if (o_.header && lineNo == 1) {
      header(r.line, t);
      return;
    }
    if (r.problem.empty() && r.p.count > 0) {
      const Answer& a = answers_[r.query];
      if (!a.problem.empty()) {
        r.problem = a.problem, r.token = a.token;
      } else if (!a.height) {
        t += "none";
      } else {
        appendNumber(t, shown(*a.height), o_.precision);
        if (o_.printWorld) {
          for (int k = 0; k < 3; ++k)
            t += r.p.separator, appendNumber(t, k == 2 ? shown(a.world[k]) : a.world[k], o_.precision);
        }
      }
    }
    if (!r.problem.empty()) t += r.token;
    if (r.problem.empty() || r.p.count > 0) passThrough(t, r.p);
    t += '\n';
  }

  // The header's coordinate names become the answer's; its other names pass through.
  void header(std::string_view line, std::string& t) const {
    const int want = o_.queryZ ? 3 : 2;
    PointLine p;
    std::size_t i = 0;
    for (int k = 0; k < want; ++k) {
      while (i < line.size() && isSeparator(line[i])) ++i;
      while (i < line.size() && !isSeparator(line[i])) ++i;
    }
    if (i < line.size()) p.separator = line[i] == ',' || line[i] == '\t' ? line[i] : ' ';
    while (i < line.size() && isSeparator(line[i])) ++i;
    std::string_view rest = line.substr(i);
    if (!rest.empty() && rest.back() == '\r') rest.remove_suffix(1);
    p.rest = rest;
    const char s = p.separator;
    t += "height";
    if (o_.printWorld) (((t += s) += 'x') += s) += 'y', (t += s) += 'z';
    passThrough(t, p);
    t += '\n';
  }

  double shown(double h) const { return roundNoise_ ? withoutNoise(h) : h; }

  static void passThrough(std::string& t, const PointLine& p) {
    if (!p.rest.empty()) t += p.separator, t += p.rest;
  }

  const SampleOptions& o_;
  const Surface& surface_;
  OGRCoordinateTransformation* transform_;
  std::ostream& out_;
  std::ostream& err_;
  std::string where_;
  bool roundNoise_ = false;
  std::uint64_t lineNo_ = 0;
  bool failed_ = false;
  std::vector<LineResult> results_;
  std::vector<Query> queries_;
  std::vector<Answer> answers_;
};

}  // namespace

bool readLines(const SampleOptions& options, const Surface& surface, OGRCoordinateTransformation* transform,
               std::istream& in, std::ostream& out, std::ostream& err, const std::string& where, bool integerSource) {
  LineLoop loop(options, surface, transform, out, err, where, integerSource);
  return loop.run(in);
}

}  // namespace qota::tools::sampling
