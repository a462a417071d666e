#include "viewshed_sweep.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <thread>
#include <vector>

namespace qota::sweep {

namespace {

constexpr double kEps = std::numeric_limits<double>::epsilon();
constexpr std::uint64_t kFlatId = std::uint64_t{1} << 63;  // (lineOf's ids stay below)
constexpr double kInf = std::numeric_limits<double>::infinity();

// A triangle side's line in a quadrant's (m, w) plane: w = a + b m, with a bound on the rounding
// of that value for |m| <= 1, and `reach`: the slack over the least distance t (in columns) at
// which a line of sight crosses the side, so that the slack's share of the bound at a value w is
// reach (1 + |w|) (a height error at distance t is an angle error over t).
struct Line {
  double a = -kInf, b = 0, rounding = 0, reach = 0;
  std::uint64_t id = 0;  // 0: no line (no terrain: minus infinity)
  double at(double m) const { return a + b * m; }
};

// A piece of an envelope: on [m0, m1] the highest crossing is on `line`, to within the line's own
// error bound and `extra` (the bound of a line that came within its error of it).
struct Piece {
  double m0, m1;
  Line line;
  double extra;
};

void push(std::vector<Piece>& out, double m0, double m1, const Line& line, double extra) {
  if (!(m1 > m0)) return;
  if (!out.empty() && out.back().line.id == line.id && out.back().m1 == m0) {
    out.back().m1 = m1;
    out.back().extra = std::max(out.back().extra, extra);
    return;
  }
  out.push_back({m0, m1, line, extra});
}

// Where each grid row and column has data: the first and last valid pixel (first > last: none).
// (Left empty without voids: every row and column has data to its ends.)
struct Extents {
  std::vector<int> rowFirst, rowLast, columnFirst, columnLast;

  Extents() = default;
  explicit Extents(const Grid& g)
      : rowFirst(g.height, g.width), rowLast(g.height, -1), columnFirst(g.width, g.height), columnLast(g.width, -1) {
    for (int r = 0; r < g.height; ++r) {
      const std::uint8_t* v = g.valid.data() + static_cast<std::size_t>(r) * g.width;
      for (int c = 0; c < g.width; ++c) {
        if (!v[c]) continue;
        rowFirst[r] = std::min(rowFirst[r], c), rowLast[r] = c;
        columnFirst[c] = std::min(columnFirst[c], r), columnLast[c] = r;
      }
    }
  }
};

class Quadrant {
 public:
  // q: 0 east (columns increasing), 1 west, 2 south (rows increasing), 3 north: the quadrant's
  // columns X run away from the eye, its rows Y across, whatever the grid's axes.
  // [mLo, mHi): the part of the quadrant's slopes m this sweep answers (minus and plus infinity
  // at the ends). Each part is swept alone, with its own envelopes over its own slopes (a line of
  // sight's verdict needs the terrain under it alone), so that any number of threads share the
  // quadrants evenly.
  Quadrant(const Grid& g, const Extents& extents, const Eye& eye, int q, double mLo, double mHi, double targetHeight,
           double slack, bool voids, std::span<Verdict> out)
      : g_(g), eye_(eye), q_(q), mLo_(mLo), mHi_(mHi), target_(targetHeight), slack_(slack), voids_(voids), out_(out) {
    const int w = g.width, h = g.height;
    const std::ptrdiff_t W = w;
    switch (q) {
      case 0:
        K_ = w, J_ = h, base_ = 0, sk_ = 1, sj_ = W, ox_ = eye.x, oy_ = eye.y, s_ = 1;
        break;
      case 1:
        K_ = w, J_ = h, base_ = W - 1, sk_ = -1, sj_ = W, ox_ = (w - 1) - eye.x, oy_ = eye.y, s_ = -1;
        break;
      case 2:
        K_ = h, J_ = w, base_ = 0, sk_ = W, sj_ = 1, ox_ = eye.y, oy_ = eye.x, s_ = 1;
        break;
      default:
        K_ = h, J_ = w, base_ = (h - 1) * W, sk_ = -W, sj_ = 1, ox_ = (h - 1) - eye.y, oy_ = eye.x, s_ = -1;
    }
    oz_ = eye.z;
    prevZ_.resize(J_), curZ_.resize(J_), prevV_.resize(J_), curV_.resize(J_);
    live(extents);
  }

  // Sweeps the quadrant; false when keepGoing said stop (asked every few columns when given).
  bool run(Counts& counts, const std::function<bool()>& keepGoing) {
    const int k0 = static_cast<int>(std::floor(ox_)) + 1;
    gather(k0 - 1, prevZ_, prevV_);
    Line none;
    envelope_.assign(1, Piece{std::max(-1.0, mLo_), std::min(1.0, mHi_), none, 0});
    clean_ = sinceHigh_ = sinceLow_ = doneHigh_ = doneLow_ = envelope_;
    for (int k = k0; k < K_; ++k) {
      if (keepGoing && (k - k0) % 64 == 63 && !keepGoing()) return false;
      gather(k, curZ_, curV_);
      const double t2 = k - ox_, t1 = t2 - 1;
      if (voids_) addVoids(t1, t2);
      answer(k, t1, t2, counts);
      if (k + 1 < K_) {
        // The slopes of the pixels with data in the columns ahead, in this part: no pixel is
        // answered elsewhere, so the envelopes are neither kept nor read there (on a DEM with
        // void margins, lines of sight that have left the data for good). None: the part is done.
        const double lo = std::max({liveLo_[k + 1], -1.0, -oy_ / (t2 + 1), mLo_});
        const double hi = std::min({liveHi_[k + 1], 1.0, (J_ - 1 - oy_) / (t2 + 1), mHi_});
        if (!(hi > lo)) break;
        strip(k, t1, t2, lo, hi);
        merge(lo, hi);
      }
      std::swap(prevZ_, curZ_);
      std::swap(prevV_, curV_);
    }
    return true;
  }

 private:
  std::size_t index(int k, int j) const { return static_cast<std::size_t>(base_ + k * sk_ + j * sj_); }

  // liveLo_[k], liveHi_[k]: slopes below and above those of every pixel with data in columns k
  // and beyond (a row's margin each way, so that the range has width wherever it holds a
  // pixel); empty (lo > hi) where no pixel ahead has data.
  void live(const Extents& e) {
    if (e.rowFirst.empty()) {  // (no voids: every slope the raster holds)
      liveLo_.assign(static_cast<std::size_t>(K_) + 1, -kInf);
      liveHi_.assign(static_cast<std::size_t>(K_) + 1, kInf);
      return;
    }
    liveLo_.assign(static_cast<std::size_t>(K_) + 1, kInf);
    liveHi_.assign(static_cast<std::size_t>(K_) + 1, -kInf);
    const bool rows = q_ >= 2;  // a quadrant column is a grid row
    for (int k = K_ - 1; k >= 0; --k) {
      liveLo_[k] = liveLo_[k + 1], liveHi_[k] = liveHi_[k + 1];
      const double t = k - ox_;
      if (!(t > 0)) continue;  // (the sweep reads columns ahead of the eye only)
      const int line = (q_ == 0 || q_ == 2) ? k : K_ - 1 - k;
      const int first = rows ? e.rowFirst[line] : e.columnFirst[line];
      const int last = rows ? e.rowLast[line] : e.columnLast[line];
      if (first > last) continue;
      liveLo_[k] = std::min(liveLo_[k], (first - 1 - oy_) / t);
      liveHi_[k] = std::max(liveHi_[k], (last + 1 - oy_) / t);
    }
  }

  // Column k's heights and validity, on the rows its strip and its pixels can need: those
  // within kMargin rows of the lines of sight of this part's slopes (and |m| <= 1) at the column.
  static constexpr int kMargin = 5;
  void gather(int k, std::vector<double>& z, std::vector<std::uint8_t>& v) {
    const auto rows = [&](int column, int& j0, int& j1) {
      const double t = std::max(std::fabs(column - ox_), 1.0);
      j0 = std::max(0, static_cast<int>(std::floor(oy_ + std::max(-1.0, mLo_) * t)) - kMargin);
      j1 = std::min(J_ - 1, static_cast<int>(std::ceil(oy_ + std::min(1.0, mHi_) * t)) + kMargin);
    };
    int j0, j1;
    rows(k, j0, j1);
    if (sj_ == 1) {  // (north and south: a column of the quadrant is a row of the grid)
      for (int j = j0; j <= j1; ++j) {
        const std::size_t i = index(k, j);
        z[j] = g_.z[i], v[j] = g_.valid[i];
      }
      return;
    }
    // East and west: the quadrant's columns are the grid's, one pixel a row apart; read
    // kColumns of them in one pass over the rows (a cache line a row instead of one a pixel),
    // kept for the columns that follow. (The rows the last of them needs hold the others'.)
    if (k < blockFirst_ || k >= blockFirst_ + kColumns) {
      blockFirst_ = k;
      const int count = std::min(kColumns, K_ - k);
      int b0, b1;
      rows(k + count - 1, b0, b1);
      b0 = std::min(b0, j0), b1 = std::max(b1, j1);
      blockZ_.resize(static_cast<std::size_t>(J_) * kColumns), blockV_.resize(blockZ_.size());
      constexpr int kAhead = 16;  // rows: the lines lie a page or more apart, out of the prefetcher's sight
      for (int j = b0; j <= b1; ++j) {
        if (j + kAhead <= b1) {
          const std::size_t ahead = index(k, j + kAhead);
          __builtin_prefetch(&g_.z[ahead]), __builtin_prefetch(&g_.valid[ahead]);
        }
        for (int c = 0; c < count; ++c) {
          const std::size_t i = index(k + c, j), at = static_cast<std::size_t>(j) * kColumns + c;
          blockZ_[at] = g_.z[i], blockV_[at] = g_.valid[i];
        }
      }
    }
    const int c = k - blockFirst_;
    for (int j = j0; j <= j1; ++j) {
      const std::size_t at = static_cast<std::size_t>(j) * kColumns + c;
      z[j] = blockZ_[at], v[j] = blockV_[at];
    }
  }

  // Whether this quadrant answers pixel (k, j): the grid's own offsets decide, the same
  // expressions in every quadrant, so each pixel is exactly one quadrant's (the one under the eye
  // none's).
  bool owns(int k, int j) const {
    const int c = q_ == 0 ? k : q_ == 1 ? g_.width - 1 - k : j;
    const int r = q_ <= 1 ? j : q_ == 2 ? k : g_.height - 1 - k;
    const double dx = c - eye_.x, dy = r - eye_.y, ax = std::fabs(dx), ay = std::fabs(dy);
    switch (q_) {
      case 0:
        return dx > 0 && ay <= ax;
      case 1:
        return dx < 0 && ay <= ax;
      case 2:
        return dy > 0 && ax < ay;
      default:
        return dy < 0 && ax < ay;
    }
  }

  // The line of the side from (k1, j1) to (k2, j2) (k1 = k - 1 or k, heights from the caches):
  // the plane through the eye and the side meets every line of sight (1, m, w) where
  // n . (1, m, w) = 0, n = d1 x d2. Sides whose ground line passes through the eye are left out
  // (the lines of sight along them cross them only at the eye; their far corner is another
  // side's end).
  bool lineOf(int k, int k1, int j1, int k2, int j2, int family, double nearest, Line& out) const {
    const double z1 = k1 == k ? curZ_[j1] : prevZ_[j1], z2 = k2 == k ? curZ_[j2] : prevZ_[j2];
    const double ax = k1 - ox_, ay = j1 - oy_, az = z1 - oz_;
    const double bx = k2 - ox_, by = j2 - oy_, bz = z2 - oz_;
    const double nx = ay * bz - az * by, ny = az * bx - ax * bz, nz = ax * by - ay * bx;
    if (nz == 0) return false;
    out.a = -nx / nz, out.b = -ny / nz;
    const double size = std::fabs(out.a) + std::fabs(out.b);
    // Rounding: the differences, the cross product's terms, the divisions and a + b m, with room.
    const double terms = std::fabs(ay * bz) + std::fabs(az * by) + std::fabs(az * bx) + std::fabs(ax * bz) +
                         size * (std::fabs(ax * by) + std::fabs(ay * bx));
    out.rounding = 64 * kEps * (size + terms / std::fabs(nz));
    if (nearest > 0) {
      out.reach = slack_ / nearest;
    } else {
      // A side of the eye's own strip: its crossings lie at least its distance from the eye away,
      // which is at most sqrt(2) t along a line of sight with |m| <= 1.
      const double dx = bx - ax, dy = by - ay, u = std::clamp(-(ax * dx + ay * dy) / (dx * dx + dy * dy), 0.0, 1.0);
      const double distance = std::hypot(ax + u * dx, ay + u * dy);
      out.reach = distance > 0 ? slack_ * std::sqrt(2.0) / distance : kInf;
    }
    out.id = (static_cast<std::uint64_t>(k) * static_cast<std::uint64_t>(J_) + static_cast<std::uint64_t>(j1)) * 3 +
             static_cast<std::uint64_t>(family) + 1;
    return true;
  }

  // The bound on a line's value error over [m0, m1]: its rounding and the slack, which grows as
  // the crossing nears the eye (a height error at distance t is an angle error / t).
  static double bound(const Line& l, double m0, double m1) {
    return l.id == 0 ? 0 : boundAt(l, std::max(std::fabs(l.at(m0)), std::fabs(l.at(m1))));
  }

  // The sides a line of sight of slope m crosses in strip k (between columns k - 1 and k),
  // strictly after t = tStart and strictly before column k; with `right`, the column-k side as
  // well. At most one or two of each kind: a strip is one column wide and |m| <= 1.
  int crossings(int k, double m, double tStart, bool right, Line* out) const {
    const double t2 = k - ox_, t1 = t2 - 1;
    const double x0 = t1 > 0 ? static_cast<double>(k - 1) : ox_ + tStart;
    const double ya = oy_ + m * tStart, yb = oy_ + m * t2;
    const double nearest = t1 > 0 ? t1 : 0.0;
    int n = 0;
    if (right) {
      const int j = std::clamp(static_cast<int>(std::floor(yb)), 0, J_ - 2);
      if (lineOf(k, k, j, k, j + 1, 0, t2, out[n])) ++n;
    }
    const double ylo = std::min(ya, yb), yhi = std::max(ya, yb);
    for (int j = static_cast<int>(std::floor(ylo)) + 1; j < yhi; ++j) {
      if (j > ylo && j >= 0 && j < J_ && lineOf(k, k - 1, j, k, j, 1, nearest, out[n])) ++n;
    }
    // Diagonals: X - Y = c (s = 1, corners (k-1, k-1-c) and (k, k-c)) or X + Y = c (s = -1,
    // corners (k-1, c-k+1) and (k, c-k)).
    const double ca = s_ > 0 ? x0 - ya : x0 + ya, cb = s_ > 0 ? k - yb : k + yb;
    const double clo = std::min(ca, cb), chi = std::max(ca, cb);
    for (long c = static_cast<long>(std::floor(clo)) + 1; c < chi; ++c) {
      if (!(c > clo)) continue;
      const long j1 = s_ > 0 ? k - 1 - c : c - k + 1, j2 = s_ > 0 ? j1 + 1 : j1 - 1;
      if (j1 < 0 || j2 < 0 || j1 >= J_ || j2 >= J_) continue;
      if (lineOf(k, k - 1, static_cast<int>(j1), k, static_cast<int>(j2), 2, nearest, out[n])) ++n;
    }
    return n;
  }

  // Squares of strip k with a void corner: the slopes m of the lines of sight that touch them
  // join voidM_ (sorted, disjoint, closed and padded for rounding).
  void addVoids(double t1, double t2) {
    std::vector<std::pair<double, double>>& fresh = freshVoids_;  // this strip's
    fresh.clear();
    // Squares that lines of sight of this part's slopes (|m| <= 1) can touch in this strip
    // (and that were gathered): a square j holds slopes from (j - oy) / t to (j + 1 - oy) / t,
    // t in [t1, t2], and m t1 differs from m t2 by at most 1.
    const int j0 = std::max(0, static_cast<int>(std::floor(oy_ + std::max(-1.0, mLo_) * t2)) - 2);
    const int j1 = std::min(J_ - 2, static_cast<int>(std::ceil(oy_ + std::min(1.0, mHi_) * t2)) + 1);
    for (int j = j0; j <= j1; ++j) {
      if (prevV_[j] && prevV_[j + 1] && curV_[j] && curV_[j + 1]) continue;
      double lo, hi;
      if (t1 > 0) {
        lo = std::min((j - oy_) / t1, (j - oy_) / t2), hi = std::max((j + 1 - oy_) / t1, (j + 1 - oy_) / t2);
      } else if (j <= oy_ && oy_ <= j + 1) {
        lo = -kInf, hi = kInf;  // the eye's own square
      } else if (j > oy_) {
        lo = (j - oy_) / t2, hi = kInf;
      } else {
        lo = -kInf, hi = (j + 1 - oy_) / t2;
      }
      lo -= 1e-12 * (1 + std::fabs(lo)), hi += 1e-12 * (1 + std::fabs(hi));
      if (!fresh.empty() && lo <= fresh.back().second) {
        fresh.back().second = std::max(fresh.back().second, hi);
      } else {
        fresh.emplace_back(lo, hi);
      }
    }
    if (fresh.empty()) return;
    // Lines of sight touching a void for the first time: the envelope so far (the columns before
    // this strip) is their terrain before the first void (clean_).
    difference(fresh, voidM_, firstTouch_);
    if (!firstTouch_.empty()) overlay(clean_, envelope_, firstTouch_);
    std::vector<std::pair<double, double>> all;
    all.reserve(voidM_.size() + fresh.size());
    std::merge(voidM_.begin(), voidM_.end(), fresh.begin(), fresh.end(), std::back_inserter(all));
    voidM_.clear();
    for (const auto& v : all) {
      if (!voidM_.empty() && v.first <= voidM_.back().second) {
        voidM_.back().second = std::max(voidM_.back().second, v.second);
      } else {
        voidM_.push_back(v);
      }
    }
  }

  // The bound of a line's value v at m (bound() at one point).
  static double boundAt(const Line& l, double v) { return l.rounding + l.reach * (1 + std::fabs(v)); }

  // The sides that the line of sight to pixel (k, j) (slope m) crosses in strip k, to consider.
  template <class Consider>
  void localCrossings(int k, double t1, double tStart, int j, double m, Line* lines, const Consider& consider) const {
    if (t1 > 0) {
      // A whole strip: a line of sight ending at a corner (k, j) of column k crosses no row
      // line inside it (|m| <= 1) and one diagonal at most: from (k - 1, j) to (k, j + s),
      // when it comes from that side (m < 0 for s = 1, m > 0 for s = -1).
      if ((s_ > 0 ? m < 0 : m > 0) && lineOf(k, k - 1, j, k, j + s_, 2, t1, lines[0])) {
        const double v = lines[0].at(m);
        consider(v, boundAt(lines[0], v));
      }
      return;
    }
    const int n = crossings(k, m, tStart, false, lines);
    for (int i = 0; i < n; ++i) {
      const double v = lines[i].at(m);
      consider(v, boundAt(lines[i], v));
    }
  }

  // The verdicts of column k's pixels: the envelope of the columns before (envelope_), then the
  // sides crossed in this strip.
  void answer(int k, double t1, double t2, Counts& counts) {
    const double tStart = std::max(t1, 0.0);
    // This part's rows: those whose slope m = (j - oy) / t2 lies in [mLo, mHi) (the same
    // expression in every part, so each pixel is one part's), |m| <= 1.
    const int jlo = std::max(0, static_cast<int>(std::floor(oy_ + std::max(-1.0, mLo_) * t2)) - 1),
              jhi = std::min(J_ - 1, static_cast<int>(std::ceil(oy_ + std::min(1.0, mHi_) * t2)) + 1);
    std::size_t piece = 0, cleanPiece = 0, highPiece = 0, lowPiece = 0, donePiece = 0, doneLowPiece = 0, gap = 0,
                freshGap = 0;
    Line lines[8];
    // The bound on a height compared at distance t2 (the pixel's own rounding and slack).
    const double ownSlack = slack_ / t2;
    for (int j = jlo; j <= jhi; ++j) {
      const double m = (j - oy_) / t2;
      if (!(m >= mLo_ && m < mHi_) || !curV_[j] || !owns(k, j)) continue;
      const std::size_t at = index(k, j);
      Verdict verdict = Verdict::Undecided;
      while (gap < voidM_.size() && voidM_[gap].second < m) ++gap;
      const bool touched = gap < voidM_.size() && m >= voidM_[gap].first;  // a void on the way
      const double wP = (curZ_[j] + target_ - oz_) / t2;
      const double own = 8 * kEps * std::fabs(wP) + ownSlack * (1 + std::fabs(wP));
      double upper = -kInf, lower = -kInf;  // the highest crossing lies between them
      const auto consider = [&](double v, double err) {
        upper = std::max(upper, v + err), lower = std::max(lower, v - err);
      };
      // The envelope's pieces at m: the one that holds it, and a neighbour when m is within
      // rounding of its end (for the upper bound only: a line is a crossing only on its piece).
      const auto read = [&](const std::vector<Piece>& env, std::size_t& piece, bool& inside) {
        while (piece + 1 < env.size() && env[piece].m1 < m) ++piece;
        const double near = 1e-12 * (1 + std::fabs(m));
        const Piece& e = env[piece];
        inside = e.m0 <= m && m <= e.m1;
        if (e.line.id != 0) {
          const double v = e.line.at(m), err = std::max(boundAt(e.line, v), e.extra);
          if (inside) {
            consider(v, err);
          } else {
            upper = std::max(upper, v + err);
          }
        }
        for (std::size_t p : {piece - 1, piece + 1}) {
          if (p >= env.size()) continue;
          const Piece& f = env[p];
          if (f.line.id == 0 || m < f.m0 - near || m > f.m1 + near) continue;
          const double v = f.line.at(m), err = std::max(boundAt(f.line, v), f.extra);
          if (f.m0 <= m && m <= f.m1) {
            consider(v, err);
          } else {
            upper = std::max(upper, v + err);
          }
        }
      };
      bool inside = false;
      if (touched) {
        // Hidden by the terrain before the first void; or by one piece of terrain after it
        // (between voids, or since the last one) with crossings both above and below the line
        // (the terrain between them meets it); or visible over everything.
        read(clean_, cleanPiece, inside);
        bool hidden = lower > wP + own;
        while (freshGap < freshVoids_.size() && freshVoids_[freshGap].second < m) ++freshGap;
        const bool here = freshGap < freshVoids_.size() && m >= freshVoids_[freshGap].first;
        // A pair of envelopes (the highest crossings and, turned upside down, the lowest) read on
        // one side of m: the pieces just before it (side < 0) or just after (side > 0), the same
        // piece where m lies inside one. At a piece's end the pieces on either side may hold
        // different pieces of terrain (completed between different voids), and a witness needs
        // both its crossings in one. Returns the highest crossing's lower bound and the lowest's
        // upper bound there (minus and plus infinity where that side has none).
        const auto sideOf = [&](const std::vector<Piece>& env, std::size_t& p, int side) {
          while (p + 1 < env.size() && env[p].m1 < m) ++p;
          const Piece* e = &env[p];
          if (side < 0 ? !(e->m0 < m && m <= e->m1) : !(e->m0 <= m && m < e->m1)) {
            e = side > 0 && p + 1 < env.size() && env[p + 1].m0 <= m && m < env[p + 1].m1 ? &env[p + 1] : nullptr;
          }
          if (!e || e->line.id == 0) return -kInf;
          const double v = e->line.at(m);
          return v - std::max(boundAt(e->line, v), e->extra);
        };
        const auto pairHides = [&](const std::vector<Piece>& high, std::size_t& hp, const std::vector<Piece>& low,
                                   std::size_t& lp, double localHigh, double localLow) {
          for (int side : {-1, 1}) {
            const double highest = std::max(sideOf(high, hp, side), localHigh);
            const double lowest = std::min(-sideOf(low, lp, side), localLow);  // (low holds -w)
            if (highest > wP + own && lowest < wP - own) return true;
          }
          return false;
        };
        if (!hidden) hidden = pairHides(doneHigh_, donePiece, doneLow_, doneLowPiece, -kInf, kInf);
        if (!hidden) {
          double localHigh = -kInf, localLow = kInf;
          if (!here) {
            // The run goes on to the pixel: this strip's crossings and column k - 1's (which the
            // envelopes may have left out below the envelope) join it, and with a target above
            // the surface the pixel's ground (below the line).
            localCrossings(k, t1, tStart, j, m, lines, [&](double v, double err) {
              localHigh = std::max(localHigh, v - err), localLow = std::min(localLow, v + err);
            });
            if (t1 > 0) {
              const double ya = oy_ + m * t1;
              const int r = std::clamp(static_cast<int>(std::floor(ya)), 0, J_ - 2);
              if (lineOf(k, k - 1, r, k - 1, r + 1, 0, t1, lines[1])) {
                const double v = lines[1].at(m), err = boundAt(lines[1], v);
                localLow = std::min(localLow, v + err), localHigh = std::max(localHigh, v - err);
              }
            }
            if (target_ > 0) localLow = std::min(localLow, (curZ_[j] - oz_) / t2 + ownSlack * (1 + std::fabs(wP)));
          }
          hidden = pairHides(sinceHigh_, highPiece, sinceLow_, lowPiece, localHigh, localLow);
        }
        if (hidden) {
          verdict = Verdict::Hidden;
        } else {
          upper = lower = -kInf;
          read(envelope_, piece, inside);
          localCrossings(k, t1, tStart, j, m, lines, consider);
          if (upper < wP - own) verdict = Verdict::Visible;
        }
      } else {
        read(envelope_, piece, inside);
        if (lower > wP + own && inside) {
          verdict = Verdict::Hidden;  // hidden already (most pixels)
        } else {
          localCrossings(k, t1, tStart, j, m, lines, consider);
          if (upper < wP - own) {
            verdict = Verdict::Visible;
          } else if (lower > wP + own) {
            verdict = Verdict::Hidden;
          }
        }
      }
      out_[at] = verdict;
      if (verdict == Verdict::Undecided) {
        ++counts.undecided;
      } else {
        ++counts.decided;
      }
    }
  }

  // The envelope of strip k's sides (the column-k sides and those across the strip) over the
  // slopes [lo, hi] of the lines of sight the next columns hold: between consecutive slopes
  // through a corner of column k - 1 or k, a line of sight crosses the same few sides, whose
  // upper envelope (at most a few lines) is found directly.
  void strip(int k, double t1, double t2, double lo, double hi) {
    const double tStart = std::max(t1, 0.0);
    strip_.clear();
    stripLow_.clear();
    Line lines[8];
    // Corners' slopes in order: column k - 1 (when ahead of the eye) and column k.
    int ja = t1 > 0 ? static_cast<int>(std::ceil(oy_ + lo * t1)) : 1, jaEnd = t1 > 0 ? J_ : 0;
    int jb = static_cast<int>(std::ceil(oy_ + lo * t2));
    const auto slopeA = [&](int j) { return (j - oy_) / t1; };
    const auto slopeB = [&](int j) { return (j - oy_) / t2; };
    double from = lo;
    std::size_t piece = 0;  // the envelope's piece at `from`
    double top = 0;         // (belowEnvelope's highest corner of column k, for skipBelow)
    while (from < hi) {
      // A block of lines of sight (up to kBlock rows of column k) below the envelope all along
      // adds nothing: a crossing's w lies between its side's corners' (w is monotone along a
      // side ahead of the eye), so when every corner the block's lines of sight can cross is
      // lower than the envelope's least value there, less its error bound, the block is skipped.
      double blockEnd = hi;
      if (t1 > 0) {
        constexpr int kBlock = 32;
        blockEnd = std::min(hi, slopeB(std::max(jb, static_cast<int>(std::ceil(oy_ + from * t2))) + kBlock));
        if (blockEnd > from && belowEnvelope(from, blockEnd, t1, t2, piece, top)) {
          skipBelow(t2, from, blockEnd, top);
          from = blockEnd;
          continue;
        }
      }
      while (from < blockEnd) {
        double next = blockEnd;
        while (ja < jaEnd && slopeA(ja) <= from) ++ja;
        while (jb < J_ && slopeB(jb) <= from) ++jb;
        if (ja < jaEnd) next = std::min(next, slopeA(ja));
        if (jb < J_) next = std::min(next, slopeB(jb));
        // The block's test on this interval alone, and the same steps when it holds: a block
        // with terrain above the envelope somewhere mostly holds rows below it elsewhere.
        if (t1 > 0 && belowEnvelope(from, next, t1, t2, piece, top)) {
          skipBelow(t2, from, next, top);
          from = next;
          continue;
        }
        const int n = crossings(k, 0.5 * (from + next), tStart, true, lines);
        envelopeOn(strip_, from, next, lines, n);
        if (voids_) {
          // The lower envelope, as the upper one of the lines turned upside down.
          for (int i = 0; i < n; ++i) lines[i].a = -lines[i].a, lines[i].b = -lines[i].b;
          envelopeOn(stripLow_, from, next, lines, n);
        }
        from = next;
      }
    }
  }

  // Strip k over slopes [m0, m1] whose sides all lie below the envelope (belowEnvelope): nothing
  // for the envelope. The pieces of terrain since a void need low crossings there (to pair with
  // a high one): a bound on column k's own, the one its blocks' test has read, cheaper than the
  // strip's envelope or a line a row; where no line of sight has touched a void, none (leaving
  // crossings out of a witness, or bounding them from above, only weakens it).
  void skipBelow(double t2, double m0, double m1, double columnTop) {
    push(strip_, m0, m1, Line{}, 0);
    if (!voids_) return;
    if (touchesVoids(m0, m1)) {
      // Every line of sight here crosses a side of column k whose corners belowEnvelope has
      // just read, at a w no more than their highest's (w is linear along the side). A crossing
      // known to be no higher than that is all a witness's low crossing needs: in the lower
      // envelope (turned upside down), a flat line at minus that w, with its error bound.
      const double w = (columnTop - oz_) / t2;
      Line flat;
      flat.a = -w, flat.b = 0;
      flat.rounding = 64 * kEps * ((std::fabs(columnTop) + std::fabs(oz_)) / t2 + std::fabs(w));
      flat.reach = slack_ / t2;
      flat.id = kFlatId | ++flats_;  // (its own: push joins neighbours only on one line)
      push(stripLow_, m0, m1, flat, 0);
    } else {
      push(stripLow_, m0, m1, Line{}, 0);
    }
  }

  // Whether lines of sight of slopes in [m0, m1] have touched a void.
  bool touchesVoids(double m0, double m1) const {
    if (voidM_.empty()) return false;
    const auto after = std::lower_bound(voidM_.begin(), voidM_.end(), std::pair{m0, -kInf});
    if (after != voidM_.end() && after->first <= m1) return true;
    return after != voidM_.begin() && std::prev(after)->second >= m0;
  }

  // Whether every corner of columns k - 1 and k that lines of sight of slopes [m0, m1] can cross
  // in strip k lies below the envelope there by more than its error bound. piece: where to start
  // looking in the envelope (moves forward). columnTop: when true, column k's highest corner there.
  bool belowEnvelope(double m0, double m1, double t1, double t2, std::size_t& piece, double& columnTop) const {
    while (piece + 1 < envelope_.size() && envelope_[piece].m1 <= m0) ++piece;
    double least = kInf;
    for (std::size_t p = piece; p < envelope_.size() && envelope_[p].m0 < m1; ++p) {
      const Piece& e = envelope_[p];
      if (e.line.id == 0) return false;
      const double a = std::max(m0, e.m0), b = std::min(m1, e.m1);
      const double va = e.line.at(a), vb = e.line.at(b);
      const double err = bound(e.line, a, b);
      least = std::min(least, std::min(va, vb) - err - e.extra);
      if (!(least > -kInf)) return false;
    }
    const auto highest = [&](const std::vector<double>& z, double t, double mlo, double mhi) {
      const int j0 = std::max(0, static_cast<int>(std::floor(oy_ + mlo * t)) - 1);
      const int j1 = std::min(J_ - 1, static_cast<int>(std::ceil(oy_ + mhi * t)) + 1);
      double top = -kInf;
      for (int j = j0; j <= j1; ++j) top = std::max(top, z[j]);
      return top;
    };
    // (Heights over the eye divided by t: the corners' w; the largest w of a column is its
    // highest corner's, t being the same along a column. Column k's is skipBelow's.)
    columnTop = highest(curZ_, t2, m0, m1);
    const double top = std::max((highest(prevZ_, t1, m0, m1) - oz_) / t1, (columnTop - oz_) / t2);
    return top + 1e-9 * (1 + std::fabs(top)) < least;
  }

  // The upper envelope of a few lines over [m0, m1], onto strip_: cut where any two cross, the
  // highest at each part's middle (lines that meet at a corner, as a corner's sides do at its
  // slope, are told apart away from it, not by the rounding there).
  void envelopeOn(std::vector<Piece>& out, double m0, double m1, const Line* lines, int n) {
    if (n <= 1) {  // (most intervals cross one side: the column's)
      push(out, m0, m1, n == 0 ? Line{} : lines[0], 0);
      return;
    }
    double cuts[32];
    int count = 0;
    cuts[count++] = m0;
    for (int i = 0; i < n; ++i) {
      for (int j = i + 1; j < n; ++j) {
        if (lines[i].b == lines[j].b) continue;
        const double x = (lines[i].a - lines[j].a) / (lines[j].b - lines[i].b);
        if (x > m0 && x < m1) cuts[count++] = x;
      }
    }
    cuts[count++] = m1;
    std::sort(cuts + 1, cuts + count - 1);
    for (int c = 0; c + 1 < count; ++c) {
      const double lo = cuts[c], hi = cuts[c + 1];
      if (!(hi > lo)) continue;
      const double mid = 0.5 * (lo + hi);
      int top = 0;
      for (int i = 1; i < n; ++i) {
        if (lines[i].at(mid) > lines[top].at(mid)) top = i;
      }
      // Lines within their error bounds of the highest anywhere on the part widen its bound.
      double extra = 0;
      const double wt = bound(lines[top], lo, hi);
      for (int i = 0; i < n; ++i) {
        if (i == top) continue;
        const double gap = std::min(lines[top].at(lo) - lines[i].at(lo), lines[top].at(hi) - lines[i].at(hi));
        const double wi = bound(lines[i], lo, hi);
        if (gap <= wt + wi) extra = std::max(extra, wi);
      }
      push(out, lo, hi, lines[top], extra);
    }
  }

  // envelope_ = max(envelope_, strip_) over [lo, hi] (strip_ covers it, envelope_ more).
  // With voids, the others too: clean_ from strip_ where no line of sight has touched a void;
  // since the last void, the envelopes emptied where this strip touches one, then joined by the
  // strip's where it does not.
  void merge(double lo, double hi) {
    mergeInto(envelope_, strip_, lo, hi);
    if (!voids_ || voidM_.empty()) return;
    // Lines of sight that touch a void in this strip end a piece of terrain: where they had
    // crossings since the last void, those become the completed piece's (both envelopes, so the
    // pair stays one piece's), in place of an earlier one.
    // (Most strips of a slice touch no void: then nothing ends, and masking copies alone.)
    const bool fresh = !freshVoids_.empty();
    ends_.clear();
    if (fresh) {
      std::size_t v = 0;
      for (const Piece& p : sinceHigh_) {
        if (p.line.id == 0) continue;
        while (v < freshVoids_.size() && freshVoids_[v].second < p.m0) ++v;
        for (std::size_t w = v; w < freshVoids_.size() && freshVoids_[w].first < p.m1; ++w) {
          const double a = std::max(p.m0, freshVoids_[w].first), b = std::min(p.m1, freshVoids_[w].second);
          if (b > a) {
            if (!ends_.empty() && ends_.back().second >= a) {
              ends_.back().second = std::max(ends_.back().second, b);
            } else {
              ends_.emplace_back(a, b);
            }
          }
        }
      }
    }
    if (!ends_.empty()) {
      overlay(doneHigh_, sinceHigh_, ends_);
      overlay(doneLow_, sinceLow_, ends_);
    }
    // (Only lines of sight that have touched a void need these: elsewhere they stay empty. So
    // the strip joins them only on the slopes that touched a void before this strip, found by
    // search instead of a pass over the whole strip: the voids may be few.)
    difference(voidM_, freshVoids_, touchedBefore_);
    for (auto [since, add] : {std::pair{&sinceHigh_, &strip_}, std::pair{&sinceLow_, &stripLow_}}) {
      if (fresh) {
        mask(*since, freshVoids_, masked_);
        since->swap(masked_);
      }
      restrict(*add, touchedBefore_, lo, hi, masked_);
      mergeInto(*since, masked_, lo, hi);
    }
  }

  // The slopes of a that b leaves (both sorted and disjoint), onto out.
  static void difference(const std::vector<std::pair<double, double>>& a,
                         const std::vector<std::pair<double, double>>& b, std::vector<std::pair<double, double>>& out) {
    out.clear();
    std::size_t v = 0;
    for (auto [from, to] : a) {
      while (v < b.size() && b[v].second < from) ++v;
      for (std::size_t w = v; from < to; ++w) {
        if (w >= b.size() || b[w].first >= to) {
          out.emplace_back(from, to);
          break;
        }
        if (b[w].first > from) out.emplace_back(from, b[w].first);
        from = std::max(from, b[w].second);
      }
    }
  }

  // in (covering [lo, hi]) on the slopes of `keep` (sorted, disjoint), no line elsewhere in
  // [lo, hi], onto out: as masking it on keep's complement, with a search for each kept span.
  static void restrict(const std::vector<Piece>& in, const std::vector<std::pair<double, double>>& keep, double lo,
                       double hi, std::vector<Piece>& out) {
    out.clear();
    double from = lo;
    for (auto [a, b] : keep) {
      a = std::max(a, lo), b = std::min(b, hi);
      if (!(b > a)) continue;
      push(out, from, a, Line{}, 0);
      auto p = std::upper_bound(in.begin(), in.end(), a, [](double m, const Piece& q) { return m < q.m1; });
      for (; p != in.end() && p->m0 < b; ++p) push(out, std::max(p->m0, a), std::min(p->m1, b), p->line, p->extra);
      from = b;
    }
    push(out, from, hi, Line{}, 0);
  }

  // dst takes src's pieces on the slopes `where` (sorted, disjoint), keeps its own elsewhere.
  void overlay(std::vector<Piece>& dst, const std::vector<Piece>& src,
               const std::vector<std::pair<double, double>>& where) {
    // src on `where`, nothing elsewhere: the complement masked away.
    complement(where, complement_);
    mask(src, complement_, masked_);
    // dst masked on `where`, then the two joined (each slope is one's or none's).
    mask(dst, where, merged2_);
    merged_.clear();
    std::size_t u = 0, f = 0;
    double m = std::max(merged2_.front().m0, masked_.front().m0);
    const double hi = std::min(merged2_.back().m1, masked_.back().m1);
    while (m < hi && u < merged2_.size() && f < masked_.size()) {
      const Piece &p = merged2_[u], &q = masked_[f];
      const double end = std::min({p.m1, q.m1, hi});
      if (end > m) {
        const Piece& pick = q.line.id != 0 ? q : p;
        push(merged_, m, end, pick.line, pick.extra);
      }
      m = std::max(m, end);
      if (p.m1 <= m) ++u;
      if (q.m1 <= m) ++f;
    }
    dst.swap(merged_);
  }

  static void complement(const std::vector<std::pair<double, double>>& where,
                         std::vector<std::pair<double, double>>& out) {
    out.clear();
    double from = -kInf;
    for (const auto& [a, b] : where) {
      if (a > from) out.emplace_back(from, a);
      from = b;
    }
    out.emplace_back(from, kInf);
  }

  // in with no line (minus infinity) on the slopes of `voids` (sorted, disjoint), onto out.
  static void mask(const std::vector<Piece>& in, const std::vector<std::pair<double, double>>& voids,
                   std::vector<Piece>& out) {
    out.clear();
    std::size_t v = 0;
    for (std::size_t i = 0; i < in.size();) {
      const Piece& p = in[i++];
      double from = p.m0;
      while (v < voids.size() && voids[v].second < from) ++v;
      if (v >= voids.size() || voids[v].first >= p.m1) {
        // No void on this piece: it and the next ones up to the next void are kept whole.
        push(out, from, p.m1, p.line, p.extra);
        copyWhole(in, i, v < voids.size() ? voids[v].first : kInf, out, p.m1);
        continue;
      }
      for (std::size_t w = v; from < p.m1; ++w) {
        if (w >= voids.size() || voids[w].first >= p.m1) {
          push(out, from, p.m1, p.line, p.extra);
          break;
        }
        const auto [a, b] = voids[w];
        if (a > from) push(out, from, a, p.line, p.extra);
        push(out, std::max(from, a), std::min(p.m1, b), Line{}, 0);
        from = std::max(from, std::min(p.m1, b));
      }
    }
  }

  void mergeInto(std::vector<Piece>& envelope, const std::vector<Piece>& add, double lo, double hi) {
    merged_.clear();
    std::size_t u = 0, f = 0;
    while (u + 1 < envelope.size() && envelope[u].m1 <= lo) ++u;
    double m = lo;
    while (m < hi && u < envelope.size() && f < add.size()) {
      const Piece &p = envelope[u], &q = add[f];
      if (q.line.id == 0 && p.m1 < q.m1 && p.m1 < hi) {
        // Where the strip adds nothing (most slopes: its terrain below the envelope), the
        // envelope's pieces that end before the strip's piece does are copied as they are.
        const double end = std::min(q.m1, hi);
        push(merged_, m, p.m1, p.line, p.extra);
        m = p.m1;
        m = copyWhole(envelope, ++u, end, merged_, m);
        continue;
      }
      const double end = std::min({p.m1, q.m1, hi});
      if (end > m) combine(p, q, m, end);
      m = std::max(m, end);
      if (p.m1 <= m) ++u;
      if (q.m1 <= m) ++f;
    }
    envelope.swap(merged_);
  }

  // Appends in's pieces from i on that end before `end`, whole (i moves past them); returns where
  // the last of them ends (m when none). (As push would, piece by piece: in holds no two
  // neighbours on one line, which push would have joined.)
  static double copyWhole(const std::vector<Piece>& in, std::size_t& i, double end, std::vector<Piece>& out, double m) {
    const std::size_t from = i;
    while (i < in.size() && in[i].m1 < end) ++i;
    if (i == from) return m;
    out.insert(out.end(), in.begin() + static_cast<std::ptrdiff_t>(from), in.begin() + static_cast<std::ptrdiff_t>(i));
    return in[i - 1].m1;
  }

  void combine(const Piece& p, const Piece& q, double m0, double m1) {
    if (q.line.id == 0) return push(merged_, m0, m1, p.line, p.extra);
    if (p.line.id == 0) return push(merged_, m0, m1, q.line, q.extra);
    const double d0 = p.line.at(m0) - q.line.at(m0), d1 = p.line.at(m1) - q.line.at(m1);
    // The loser's bound joins the winner's where they come within their bounds of each other.
    const auto close = [&](double gap) {
      return gap <= bound(p.line, m0, m1) + bound(q.line, m0, m1) + p.extra + q.extra;
    };
    if (d0 >= 0 && d1 >= 0) {
      const double extra = close(std::min(d0, d1)) ? std::max({p.extra, q.extra, bound(q.line, m0, m1)}) : p.extra;
      return push(merged_, m0, m1, p.line, extra);
    }
    if (d0 <= 0 && d1 <= 0) {
      const double extra = close(-std::max(d0, d1)) ? std::max({p.extra, q.extra, bound(p.line, m0, m1)}) : q.extra;
      return push(merged_, m0, m1, q.line, extra);
    }
    const double x = std::clamp(m0 + (m1 - m0) * d0 / (d0 - d1), m0, m1);
    const double extra = std::max({p.extra, q.extra, bound(p.line, m0, m1), bound(q.line, m0, m1)});
    const Piece& first = d0 > 0 ? p : q;
    const Piece& second = d0 > 0 ? q : p;
    push(merged_, m0, x, first.line, extra);
    push(merged_, x, m1, second.line, extra);
  }

  const Grid& g_;
  Eye eye_;
  int q_;
  double mLo_, mHi_;
  double target_, slack_;
  bool voids_;
  std::span<Verdict> out_;
  int K_ = 0, J_ = 0, s_ = 1;
  std::ptrdiff_t base_ = 0, sk_ = 0, sj_ = 0;
  double ox_ = 0, oy_ = 0, oz_ = 0;
  std::vector<double> prevZ_, curZ_;
  std::vector<std::uint8_t> prevV_, curV_;
  std::vector<double> liveLo_, liveHi_;  // (live)
  std::uint64_t flats_ = 0;              // (skipBelow's lines: each its id)
  static constexpr int kColumns = 8;     // (gather: a cache line of heights)
  int blockFirst_ = -1 - kColumns;
  std::vector<double> blockZ_;
  std::vector<std::uint8_t> blockV_;
  // envelope_: every side crossed (with voids, their squares' sides too, at the heights given):
  // a line of sight above it is visible. clean_ (with voids): only the sides crossed before a
  // line of sight first touches a square with a void corner, which lie in one piece of terrain
  // with the eye (the eye below it, a crossing above: the terrain between them meets the line):
  // a line of sight below it is hidden.
  // sinceHigh_, sinceLow_ (with voids): the highest and (turned upside down) the lowest crossing
  // since a line of sight last touched a void, all in one piece of terrain that runs on to the
  // pixel: one above the line and one below it there, and the terrain between them meets it.
  // (The lowest may be a bound above a crossing, skipBelow's: still a crossing below the line.)
  // doneHigh_, doneLow_: the same for a completed piece of terrain between two voids.
  std::vector<Piece> envelope_, clean_, sinceHigh_, sinceLow_, doneHigh_, doneLow_, strip_, stripLow_, masked_, merged_,
      merged2_;
  std::vector<std::pair<double, double>> ends_, complement_, touchedBefore_, firstTouch_;
  std::vector<std::pair<double, double>> voidM_, freshVoids_;
};

}  // namespace

bool decide(const Grid& grid, const Eye& eye, double targetHeight, double slack, unsigned threads,
            std::span<Verdict> out, Counts& counts, const std::function<bool(double)>& keepGoing) {
  const bool voids = std::find(grid.valid.begin(), grid.valid.end(), 0) != grid.valid.end();
  const Extents extents = voids ? Extents(grid) : Extents();
  // Each quadrant in kParts parts of equal slope ranges, swept one by one by the threads, the
  // parts with the most pixels first. (kParts does not depend on the threads, so neither do the
  // sweep's verdicts: the parts' envelopes are cut at the same slopes whatever the count.)
  constexpr int kParts = 8;
  struct Part {
    int q;
    double mLo, mHi, pixels;
  };
  std::vector<Part> parts;
  for (int q = 0; q < 4; ++q) {
    // The quadrant's columns run from the eye to K, its rows across 0..J (as Quadrant's).
    const bool across = q < 2;
    const double K = across ? grid.width : grid.height, J = across ? grid.height : grid.width;
    const double ox = q == 0 ? eye.x : q == 1 ? grid.width - 1 - eye.x : q == 2 ? eye.y : grid.height - 1 - eye.y;
    const double oy = across ? eye.y : eye.x;
    for (int p = 0; p < kParts; ++p) {
      const double a = -1.0 + 2.0 * p / kParts, b = -1.0 + 2.0 * (p + 1) / kParts;
      // Its pixels, near enough: the rows of slopes [a, b] within the grid, column by column.
      double pixels = 0;
      for (double t = 1; t < K - ox; t += 8) {
        pixels += 8 * std::max(0.0, std::min(J, oy + b * t) - std::max(0.0, oy + a * t));
      }
      parts.push_back({q, p == 0 ? -kInf : a, p + 1 == kParts ? kInf : b, pixels});
    }
  }
  std::stable_sort(parts.begin(), parts.end(), [](const Part& x, const Part& y) { return x.pixels > y.pixels; });
  const int count = static_cast<int>(parts.size());
  std::atomic<int> nextPart{0}, partsDone{0};
  std::atomic<bool> stop{false};
  std::vector<Counts> each(parts.size());
  const unsigned workers = std::max(1u, std::min(static_cast<unsigned>(count), threads));
  const auto work = [&](unsigned worker) {
    for (int k; !stop && (k = nextPart++) < count;) {
      const Part& part = parts[k];
      Quadrant quadrant(grid, extents, eye, part.q, part.mLo, part.mHi, targetHeight, slack, voids, out);
      std::function<bool()> ask;
      if (worker == 0 && keepGoing) {
        ask = [&] {
          if (stop) return false;
          if (!keepGoing(static_cast<double>(partsDone) / count)) stop = true;
          return !stop.load();
        };
      } else {
        ask = [&] { return !stop.load(); };
      }
      if (!quadrant.run(each[k], ask)) stop = true;
      ++partsDone;
    }
  };
  std::vector<std::thread> pool;
  for (unsigned k = 1; k < workers; ++k) pool.emplace_back(work, k);
  work(0);
  for (std::thread& t : pool) t.join();
  if (stop) return false;
  for (const Counts& c : each) counts.decided += c.decided, counts.undecided += c.undecided;
  return true;
}

}  // namespace qota::sweep
