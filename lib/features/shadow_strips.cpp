#include "shadow_strips.hpp"

#include <cmath>

#include "float_bounds.hpp"
#include "shadow_facing.hpp"

namespace qota::shadow {

HorizonStrips::HorizonStrips(const LocalFrame& frame, const Eigen::Vector3d& light, double stripWidth,
                             std::vector<std::uint8_t>& facing, unsigned threads, int winding) {
  const Mesh& mesh = frame.mesh;
  const double horizontal = light.head<2>().norm();
  g_ = light.head<2>() / horizontal;
  tan_ = light.z() / horizontal;
  const unsigned parts = std::max(1u, threads);
  // Each occluder's ranges, rounded outward; and the size of the coordinates. By parts of the
  // mesh, one per thread.
  const std::size_t polygons = mesh.polygonCount();
  facing.resize(polygons);
  std::vector<std::vector<Entry>> spans(parts);
  std::vector<double> xyMax(parts, 0), zMax(parts, 0);
  inThreads(parts, [&](unsigned part) {
    const std::size_t from = polygons * part / parts, to = polygons * (part + 1) / parts;
    std::vector<Entry>& out = spans[part];
    out.reserve(to - from);  // (only the pages written are ever touched)
    double xy = 0, z = 0;
    for (std::size_t p = from; p < to; ++p) {
      const auto corners = mesh.polygon(p);
      facing[p] = facingOf(frame, corners, light, winding);
      if (!(facing[p] & kOccluder)) continue;
      double cl = INFINITY, ch = -INFINITY, ah = -INFINITY, wl = INFINITY, wh = -INFINITY;
      for (std::uint32_t k : corners) {
        const Eigen::Vector3d& v = mesh.vertices[k];
        const double a = along(v), c = across(v), w = v.z() - a * tan_;
        cl = std::min(cl, c), ch = std::max(ch, c), ah = std::max(ah, a);
        wl = std::min(wl, w), wh = std::max(wh, w);
        xy = std::max(xy, std::max(std::fabs(v.x()), std::fabs(v.y()))), z = std::max(z, std::fabs(v.z()));
      }
      // Field by field: an Entry built whole was stored in halves and reloaded whole (a stall).
      Entry& e = out.emplace_back();
      e.aHi = floatAbove(ah), e.wHi = floatAbove(wh), e.wLo = floatBelow(wl);
      e.cLo = floatBelow(cl), e.cHi = floatAbove(ch), e.tri = static_cast<std::uint32_t>(p);
    }
    xyMax[part] = xy, zMax[part] = z;
  });
  // Margins: a millionth of the coordinates' size, where rounding is below a trillionth (the
  // pixels are the same grid's vertices, of the same size).
  const double xy = *std::max_element(xyMax.begin(), xyMax.end()), z = *std::max_element(zMax.begin(), zMax.end());
  marginA_ = 1e-6 * (2 * xy + 1);
  marginW_ = 1e-6 * (z + 2 * xy * tan_ + 1);
  // The occluders' range across the light, and the sum of their widths (for the bound below).
  cLo_ = INFINITY;
  double cHi = -INFINITY, widths = 0;
  std::size_t occluders = 0;
  for (const auto& part : spans) {
    for (const Entry& e : part) {
      cLo_ = std::min(cLo_, e.cLo - marginA_), cHi = std::max(cHi, e.cHi + marginA_);
      widths += (static_cast<double>(e.cHi) - e.cLo) + 2 * marginA_;
    }
    occluders += part.size();
  }
  if (!(cLo_ <= cHi)) return;  // no occluder
  // One pixel a strip, within two bounds on memory (the width only tunes the search, never its
  // answer). An occluder goes into every strip it spans, so its copies number about its width
  // over the strips'; a DEM of wild heights or an absurd geotransform (rows a planet apart,
  // triangles wide across the whole raster) would otherwise make gigabytes of copies: at most
  // twice as many as occluders, beyond one each. And each strip is padded to 64 entries: no
  // more strips than one per 64 occluders (a raster's width in pixels is far fewer).
  const double maxStrips = std::min(4.0 * static_cast<double>(frame.pixelCount()), occluders / 64.0) + 1024;
  const double maxCopies = 2.0 * static_cast<double>(occluders) + 65536;
  perWidth_ = std::min({1 / stripWidth, maxStrips / (cHi - cLo_), maxCopies / widths});
  const std::size_t strips = strip(cHi) + 1;
  const auto stripsOf = [&](const Entry& e, std::size_t& lo, std::size_t& hi) {
    lo = strip(e.cLo - marginA_), hi = std::min(strips - 1, strip(e.cHi + marginA_));
  };
  // A counting sort into the strips: each part's entries of a strip go after the earlier
  // parts'. Each strip is padded to whole superblocks (64) with entries no ray reaches.
  std::vector<std::vector<std::uint64_t>> fill(parts, std::vector<std::uint64_t>(strips, 0));
  inThreads(parts, [&](unsigned part) {
    for (const Entry& e : spans[part]) {
      std::size_t lo, hi;
      stripsOf(e, lo, hi);
      for (std::size_t k = lo; k <= hi; ++k) ++fill[part][k];
    }
  });
  start_.assign(strips + 1, 0);
  std::vector<std::uint64_t> used(strips);
  for (std::size_t k = 0; k < strips; ++k) {
    std::uint64_t at = start_[k];
    for (unsigned part = 0; part < parts; ++part) {
      const std::uint64_t n = fill[part][k];
      fill[part][k] = at;
      at += n;
    }
    used[k] = at;
    start_[k + 1] = start_[k] + (at - start_[k] + kSuper - 1) / kSuper * kSuper;
  }
  entryCount_ = start_[strips];
  entries_.reset(new Entry[entryCount_]);  // uninitialized: every one is written below
  inThreads(parts, [&](unsigned part) {
    for (const Entry& e : spans[part]) {
      std::size_t lo, hi;
      stripsOf(e, lo, hi);
      for (std::size_t k = lo; k <= hi; ++k) entries_[fill[part][k]++] = e;
    }
  });
  spans = {};
  // Each strip by largest a, then its padding; the largest w of every block (8) and superblock
  // (64), and of every superblock with all after it in the strip. By ranges of strips.
  blockW_.assign(entryCount_ / kBlock, -INFINITY);
  superW_.assign(entryCount_ / kSuper, -INFINITY);
  laterW_.assign(entryCount_ / kSuper, -INFINITY);
  inThreads(parts, [&](unsigned part) {
    for (std::size_t k = strips * part / parts; k < strips * (part + 1) / parts; ++k) {
      Entry* E = entries_.get();
      std::sort(E + start_[k], E + used[k], [](const Entry& x, const Entry& y) { return x.aHi < y.aHi; });
      std::fill(E + used[k], E + start_[k + 1], Entry{INFINITY, -INFINITY, INFINITY, INFINITY, -INFINITY, kNoTriangle});
      float later = -INFINITY;
      for (std::uint64_t sb = start_[k + 1] / kSuper; sb-- > start_[k] / kSuper;) {
        for (std::uint64_t e = sb * kSuper; e < (sb + 1) * kSuper; ++e) {
          blockW_[e / kBlock] = std::max(blockW_[e / kBlock], E[e].wHi);
          superW_[sb] = std::max(superW_[sb], E[e].wHi);
        }
        later = std::max(later, superW_[sb]);
        laterW_[sb] = later;
      }
    }
  });
}

}  // namespace qota::shadow
