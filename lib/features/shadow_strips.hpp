// Candidate occluders for the shadow mask, found along the sun's azimuth without a tree (see the
// class). Internal to the shadow code.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cstdint>
#include <memory>
#include <vector>

#include "qota/shadow_frame.hpp"
#include "qota/vocabulary.hpp"

namespace qota::shadow {

// Candidate occluders for the light rays of a DEM's vertices, found without a light-frame tree.
// Seen from above, every ray runs along the sun's azimuth g, at a constant offset c across it,
// rising tan(altitude) per metre of a = position along g: it keeps w = z - a tan(altitude)
// constant. (c and w are coordinates across the light: a ray is a point in them.) A triangle T
// that the ray from P meets, at a point ahead of P, has c(P) in T's range of c, w(P) in T's range
// of w (w is linear over T, so that is its corners' range) and a(P) at most T's largest a. So the
// occluding triangles are binned into strips of c (one pixel wide; a triangle goes into every
// strip its c range meets), each strip sorted by the triangles' largest a, and a ray searches its
// strip from a(P) on: a binary search, then a scan that skips blocks of 8 and 64 triangles whose
// largest w is below w(P) (and stops when no later block reaches it), testing the other ranges
// per triangle. Each candidate takes the shadow quadtree's exact test (mappedTriangleAbove), and
// every triangle that test can accept is a candidate (the margins are far above the rounding), so
// the mask is the quadtree's.
class HorizonStrips {
 public:
  // The mesh's occluding triangles for a light that is not straight overhead; facing: gets
  // facingOf every triangle, found on the way. Built by `threads` threads, with the same result
  // for any number (up to the order of equal entries, which no search can tell).
  HorizonStrips(const LocalFrame& frame, const Eigen::Vector3d& light, double stripWidth,
                std::vector<std::uint8_t>& facing, unsigned threads, int winding);

  std::size_t stripCount() const { return start_.empty() ? 0 : start_.size() - 1; }
  // Entries over all strips, copies and padding included (the memory it holds, in Entry units).
  std::uint64_t entryCount() const { return entryCount_; }
  // The strip of the ray from p; stripCount() when no strip holds it.
  std::size_t stripOf(const Eigen::Vector3d& p) const {
    const double c = across(p);
    if (!(c >= cLo_) || start_.empty()) return stripCount();
    return std::min(strip(c), stripCount());
  }

  // Whether test(t) holds for a candidate t (a mesh polygon) of the ray from p. hint: where the
  // last search of this thread ended (any value will do; a nearby one is faster).
  template <class Test>
  bool anyAlong(const Eigen::Vector3d& p, std::uint64_t& hint, Test&& test) const {
    const std::size_t k = stripOf(p);
    if (k >= stripCount()) return false;
    const double c = across(p), a = along(p), w = p.z() - a * tan_;
    const double wFrom = w - marginW_, wTo = w + marginW_, aFrom = a - marginA_;
    const double cPlus = c + marginA_, cMinus = c - marginA_;
    const Entry* E = entries_.get();
    const std::uint64_t end = start_[k + 1];
    // First entry with aHi >= aFrom: a few steps from the hint when it is in this strip (the
    // pixels of a strip come nearly in order of a, a pixel or so apart: one mispredicted branch
    // where a binary search has several), else (or when that is far) a binary search.
    const auto before = [&](const Entry& x) { return x.aHi < aFrom; };
    std::uint64_t lo = start_[k], hi = end, e;
    if (hint >= lo && hint < hi) {
      constexpr std::uint64_t kSteps = 16;
      if (before(E[hint])) {
        for (lo = hint + 1; lo < hi && lo - hint < kSteps && before(E[lo]);) ++lo;
        e = lo < hi && lo - hint == kSteps
                ? static_cast<std::uint64_t>(std::partition_point(E + lo, E + hi, before) - E)
                : lo;
      } else {
        for (hi = hint; hi > lo && hint - hi < kSteps && !before(E[hi - 1]);) --hi;
        e = hi > lo && hint - hi == kSteps
                ? static_cast<std::uint64_t>(std::partition_point(E + lo, E + hi, before) - E)
                : hi;
      }
    } else {
      e = static_cast<std::uint64_t>(std::partition_point(E + lo, E + hi, before) - E);
    }
    hint = e;
    if (e >= end || !(laterW_[e / kSuper] >= wFrom)) return false;
    for (;;) {
      for (const std::uint64_t blockEnd = (e / kBlock + 1) * kBlock; e < blockEnd; ++e) {
        const Entry& x = E[e];
        if (x.wHi >= wFrom && x.wLo <= wTo && x.cLo <= cPlus && x.cHi >= cMinus && test(x.tri)) return true;
      }
      // At a block boundary: the next block in this superblock that reaches the ray, else the
      // next superblock that does (none: nothing later does).
      while (e % kSuper != 0 && !(blockW_[e / kBlock] >= wFrom)) e += kBlock;
      if (e % kSuper != 0) continue;
      if (e >= end || !(laterW_[e / kSuper] >= wFrom)) return false;
      while (!(superW_[e / kSuper] >= wFrom)) e += kSuper;
      while (!(blockW_[e / kBlock] >= wFrom)) e += kBlock;
    }
  }

 private:
  static constexpr std::uint64_t kBlock = 8, kSuper = 64;
  struct Entry {
    float aHi, wHi, wLo, cLo, cHi;  // rounded outward
    std::uint32_t tri;
  };
  double along(const Eigen::Vector3d& v) const { return v.x() * g_.x() + v.y() * g_.y(); }
  double across(const Eigen::Vector3d& v) const { return v.y() * g_.x() - v.x() * g_.y(); }
  // Monotone in c, which is all the binning needs (a multiplication, not a division).
  std::size_t strip(double c) const { return static_cast<std::size_t>((c - cLo_) * perWidth_); }

  Eigen::Vector2d g_;
  double tan_ = 0, marginA_ = 0, marginW_ = 0, cLo_ = 0, perWidth_ = 1;
  std::vector<std::uint64_t> start_;
  std::unique_ptr<Entry[]> entries_;
  std::uint64_t entryCount_ = 0;
  std::vector<float> blockW_, superW_, laterW_;
};

}  // namespace qota::shadow
