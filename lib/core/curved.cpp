#include "qota/curved.hpp"

#include <Eigen/Geometry>
#include <GeographicLib/Math.hpp>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <string>
#include <type_traits>

#include "qota/batch.hpp"
#include "qota/index.hpp"
#include "qota/error.hpp"
#include "qota/memory_budget.hpp"
#include "line_crossing.hpp"
#include "qota/predicates.hpp"

namespace qota {
namespace {

constexpr double kEps = 1.1102230246251565e-16;
constexpr double kInf = std::numeric_limits<double>::infinity();
using axial::kPadDegrees;
using GeographicLib::Math;

// The angle range around the z axis of a triangle whose edges each sweep the shorter arc between
// their ends (a great-circle arc seen from the centre, a straight edge seen from the axis).
// Vertices on the axis have no angle and are skipped: the edges to them are meridians of the
// other ends. Returns false when the triangle goes around the axis or an edge crosses it: every
// angle.
bool angleRange(const Eigen::Vector3d p[3], double& lo, double& hi) {
  double ang[3];
  int m = 0;
  for (int i = 0; i < 3; ++i) {
    if (p[i].x() != 0.0 || p[i].y() != 0.0) ang[m++] = Math::atan2d(p[i].y(), p[i].x());
  }
  if (m == 0) return false;
  double run = ang[0], total = 0;
  lo = hi = run;
  for (int i = 1; i <= m; ++i) {
    const double delta = std::remainder(ang[i % m] - ang[i - 1], 360.0);
    if (std::fabs(delta) >= 180.0 - 1e-9) return false;  // an edge through the axis
    total += delta;
    if (i < m) {
      run += delta;
      lo = std::min(lo, run), hi = std::max(hi, run);
    }
  }
  return std::fabs(total) < 180.0;  // a loop around the axis sums to +-360
}

}  // namespace

template <AxialMapping M>
CurvedIndex<M>::CurvedIndex(const Mesh& mesh, const M& mapping, const IndexOptions& options) : mapping_(mapping) {
  if (options.gridFastPath.value_or(false)) {
    throw Error(std::string(M::name()) +
                " terrain: the grid fast path (IndexOptions::gridFastPath) is for "
                "planar mappings only");
  }
  const std::size_t nv = mesh.vertices.size();
  if (nv > 0xfffffff0u) throw Error("curved terrain: more than 2^32 vertices");
  std::uint64_t fanned = 0;  // refuse what cannot fit before allocating (memory_budget.hpp)
  for (std::size_t p = 0; p < mesh.polygonCount(); ++p)
    fanned += mesh.polygon(p).size() > 2 ? mesh.polygon(p).size() - 2 : 0;
  memory::require(std::string(M::name()) + " terrain", memory::kCurvedIndex, nv, fanned);
  std::vector<Eigen::Vector3d> local(nv);
  std::vector<double> vertexHeight(nv);  // what the mapping's footprints need of each vertex
  for (std::size_t i = 0; i < nv; ++i) {
    // Non-finite vertices (nodata) are allowed while no polygon uses them.
    local[i] = mapping_.toLocal(mesh.vertices[i]);
    if (!local[i].allFinite()) continue;
    scale_ = std::max(scale_, local[i].lpNorm<1>());
    vertexHeight[i] = mapping_.footprintHeight(mesh.vertices[i]);
  }

  std::vector<Tri> tris;
  std::vector<FootBox> boxes;
  tris.reserve(mesh.polygonCount());
  boxes.reserve(mesh.polygonCount());
  const std::size_t np = mesh.polygonCount();
  for (std::size_t poly = 0; poly < np; ++poly) {
    const auto corners = mesh.polygon(poly);
    if (corners.size() < 3) {
      throw Error("curved terrain: polygon " + std::to_string(poly) + " has " + std::to_string(corners.size()) +
                  " vertices (needs 3 or more)");
    }
    for (std::uint32_t c : corners) {
      if (c >= nv) {
        throw Error("curved terrain: polygon " + std::to_string(poly) + " uses vertex " + std::to_string(c) + " of " +
                    std::to_string(nv));
      }
      if (!local[c].allFinite()) {
        throw Error("curved terrain: polygon " + std::to_string(poly) + " uses vertex " + std::to_string(c) +
                    ", which is not finite");
      }
    }
    for (std::size_t k = 1; k + 1 < corners.size(); ++k) {
      const std::uint32_t id[3] = {corners[0], corners[k], corners[k + 1]};
      const Eigen::Vector3d p[3] = {local[id[0]], local[id[1]], local[id[2]]};
      const double h[3] = {vertexHeight[id[0]], vertexHeight[id[1]], vertexHeight[id[2]]};
      Tri t{};
      FootBox box;
      if (!makeTriangle(p, h, static_cast<std::uint32_t>(poly), t, box)) {
        ++stats_.leftOut;
        continue;
      }
      tris.push_back(t);
      boxes.push_back(box);
    }
  }
  if (tris.size() >= Quadtree::kInner) throw Error("curved terrain: too many triangles");
  const auto count = static_cast<std::uint32_t>(tris.size());

  // The tree's domain: the union of the footprint boxes, so that a regional terrain (a DEM tile)
  // gets a tree over its own area, not over the whole globe; all of u when a box crosses the
  // seam.
  Box2 root{kInf, kInf, -kInf, -kInf};
  for (const FootBox& b : boxes) {
    root.ulo = std::min(root.ulo, b.ulo), root.uhi = std::max(root.uhi, b.uhi);
    root.vlo = std::min(root.vlo, b.vlo), root.vhi = std::max(root.vhi, b.vhi);
  }
  if (root.uhi > 180.0) root.ulo = -180.0, root.uhi = 180.0;

  // Morton order of the box centres, so the triangles of one leaf sit together in memory.
  std::vector<std::uint64_t> key(count);
  for (std::uint32_t i = 0; i < count; ++i) {
    const double cu = std::remainder(0.5 * (boxes[i].ulo + boxes[i].uhi), 360.0);
    const double cv = 0.5 * (boxes[i].vlo + boxes[i].vhi);
    const auto qu = static_cast<std::uint64_t>(std::clamp((cu + 180.0) / 360.0, 0.0, 1.0) * 65535.0);
    const double fv = root.vhi > root.vlo ? (cv - root.vlo) / (root.vhi - root.vlo) : 0.0;
    const auto qv = static_cast<std::uint64_t>(std::clamp(fv, 0.0, 1.0) * 65535.0);
    std::uint64_t k = 0;
    for (int bit = 0; bit < 16; ++bit) {
      k |= ((qu >> bit) & 1u) << (2 * bit) | ((qv >> bit) & 1u) << (2 * bit + 1);
    }
    key[i] = k << 32 | i;
  }
  std::sort(key.begin(), key.end());
  tris_.resize(count);
  std::vector<FootBox> sorted(count);
  for (std::uint32_t i = 0; i < count; ++i) {
    const auto src = static_cast<std::uint32_t>(key[i]);
    tris_[i] = tris[src];
    sorted[i] = boxes[src];
  }
  std::vector<Tri>().swap(tris);
  boxes.swap(sorted);

  for (std::uint32_t i = 0; i < count; ++i) addToPolarLists(i, boxes[i]);

  // Size floor: half the median footprint extent (see Quadtree).
  double minU = 0, minV = 0;
  if (count > 0) {
    std::vector<double> su(count), sv(count);
    for (std::uint32_t i = 0; i < count; ++i) {
      su[i] = boxes[i].uhi - boxes[i].ulo;
      sv[i] = boxes[i].vhi - boxes[i].vlo;
    }
    std::nth_element(su.begin(), su.begin() + count / 2, su.end());
    std::nth_element(sv.begin(), sv.begin() + count / 2, sv.end());
    minU = 0.5 * su[count / 2], minV = 0.5 * sv[count / 2];
  }
  tree_.build(
      count, root, options.tree, [this](std::uint32_t i, const Box2& b) { return overlaps(i, b); }, minU, minV);

  stats_.polygons = np;
  stats_.triangles = count;
  stats_.vertices = nv;
  stats_.polarNorth = polarNorth_.size();
  stats_.polarSouth = polarSouth_.size();
  stats_.domain = root;
  stats_.tree = tree_.stats();
  stats_.memoryBytes = stats_.tree.memoryBytes + tris_.size() * sizeof(Tri) +
                       (polarNorth_.size() + polarSouth_.size()) * sizeof(std::uint32_t);
}

// The record and footprint box of the triangle with local corners p (vertexHeight: the corners'
// footprintHeight). False for a triangle of zero area.
template <AxialMapping M>
bool CurvedIndex<M>::makeTriangle(const Eigen::Vector3d (&p)[3], const double (&vertexHeight)[3], std::uint32_t poly,
                                  Tri& t, FootBox& box) const {
  const Eigen::Vector3d n = (p[1] - p[0]).cross(p[2] - p[0]);
  if (n.squaredNorm() == 0.0) return false;
  t = Tri{};
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) t.p[i][j] = p[i][j];
    t.n[i] = n[i];
  }
  t.na = n.dot(p[0]);
  t.polygon = poly;

  const bool allAngles = !angleRange(p, box.ulo, box.uhi) || box.uhi - box.ulo > 360.0 - 2 * kPadDegrees;
  if (allAngles) {
    box.ulo = -180.0, box.uhi = 180.0;
  } else {
    box.ulo -= kPadDegrees, box.uhi += kPadDegrees;
    const double shift = 360.0 * std::floor((box.ulo + 180.0) / 360.0);
    box.ulo -= shift, box.uhi -= shift;
  }
  mapping_.footprintV(p, vertexHeight, scale_, box.vlo, box.vhi);
  if (M::kPoles && allAngles) {
    // A triangle around the axis may contain a pole, which no vertex or edge reaches.
    double tp;
    const MappedDomain domain = mapping_.domain();
    if (hits(t, lineAt(0.0, domain.vhi), tp)) box.vhi = domain.vhi;
    if (hits(t, lineAt(0.0, domain.vlo), tp)) box.vlo = domain.vlo;
  }
  // Rounded outward to float for the record's quick reject.
  t.ulo = std::nextafter(static_cast<float>(box.ulo), -INFINITY);
  t.uhi = std::nextafter(static_cast<float>(box.uhi), INFINITY);
  t.vlo = std::nextafter(static_cast<float>(box.vlo), -INFINITY);
  t.vhi = std::nextafter(static_cast<float>(box.vhi), INFINITY);
  return true;
}

// The polar lists: the triangles the exact test finds on the line of each pole.
template <AxialMapping M>
void CurvedIndex<M>::addToPolarLists(std::uint32_t i, const FootBox& box) {
  if (!M::kPoles) return;
  const MappedDomain domain = mapping_.domain();
  double t;
  if (box.vhi >= domain.vhi && hits(tris_[i], lineAt(0.0, domain.vhi), t)) polarNorth_.push_back(i);
  if (box.vlo <= domain.vlo && hits(tris_[i], lineAt(0.0, domain.vlo), t)) polarSouth_.push_back(i);
}

template <AxialMapping M>
typename CurvedIndex<M>::Line CurvedIndex<M>::lineAt(double u, double v) const {
  const AxialLine a = mapping_.axialLine(u, v);
  Line line{a.s, {a.d[0], a.d[1], a.d[2]}, a.hOffset, 0.0};
  const double r = scale_ + std::fabs(line.s);
  line.bound = 64.0 * kEps * r * r;
  return line;
}

template <AxialMapping M>
int CurvedIndex<M>::edgeSign(const double* a, const double* b, const Line& line, double bound) const {
  // d . (a x b) - s (d_x (a_y - b_y) - d_y (a_x - b_x)) = det[a - O; b - O; d]. Swapping a and b
  // negates every rounded term exactly, so neighbours sharing the edge see opposite signs.
  const double* d = line.d;
  double val =
      d[0] * (a[1] * b[2] - a[2] * b[1]) + d[1] * (a[2] * b[0] - a[0] * b[2]) + d[2] * (a[0] * b[1] - a[1] * b[0]);
  if (line.s != 0.0) val -= line.s * (d[0] * (a[1] - b[1]) - d[1] * (a[0] - b[0]));
  if (val > bound) return 1;
  if (val < -bound) return -1;
  // The bound covers the rounding of the shifted corners below, so both paths give the sign of
  // one geometry: the corners moved to their rounded offsets from O.
  const double as[3] = {a[0], a[1], a[2] - line.s};
  const double bs[3] = {b[0], b[1], b[2] - line.s};
  return orient3dSign(as, bs, d);
}

template <AxialMapping M>
bool CurvedIndex<M>::hits(const Tri& t, const Line& line, double& tOut) const {
  const int s0 = edgeSign(t.p[0], t.p[1], line, line.bound);
  const int s1 = edgeSign(t.p[1], t.p[2], line, line.bound);
  if (s0 * s1 < 0) return false;
  const int s2 = edgeSign(t.p[2], t.p[0], line, line.bound);
  if (s0 * s2 < 0 || s1 * s2 < 0) return false;
  if (s0 == 0 && s1 == 0 && s2 == 0) return false;  // the line lies in the triangle's plane
  const double nd = t.n[0] * line.d[0] + t.n[1] * line.d[1] + t.n[2] * line.d[2];
  if (nd == 0.0) return false;
  tOut = (t.na - line.s * t.n[2]) / nd;
  return tOut > 0.0;
}

template <AxialMapping M>
bool CurvedIndex<M>::polar(double v) const {
  return M::kPoles && (v == mapping_.domain().vhi || v == mapping_.domain().vlo);
}

template <AxialMapping M>
bool CurvedIndex<M>::validQuery(double u, double v) const {
  if (!std::isfinite(u) || !std::isfinite(v)) return false;
  return v >= mapping_.domain().vlo && v <= mapping_.domain().vhi;
}

template <AxialMapping M>
bool CurvedIndex<M>::mapped(const Eigen::Vector3d& world, Eigen::Vector3d& m) const {
  if (!world.allFinite()) return false;
  try {
    m = mapping_.toMapped(world);  // throws at the mapping's singular point (a sphere's centre)
  } catch (const Error&) {
    return false;
  }
  return m.allFinite();
}

template <AxialMapping M>
double CurvedIndex<M>::normalizeU(double u) const {
  if (u >= -180.0 && u < 180.0) return u;
  double w = std::remainder(u, 360.0);  // [-180, 180]
  return w >= 180.0 ? w - 360.0 : w;
}

template <AxialMapping M>
template <class Visit>
void CurvedIndex<M>::forCandidates(double u, double v, const Line*& line, Line& storage, Visit&& visit) const {
  if (polar(v)) {
    storage = lineAt(u, v), line = &storage;
    for (std::uint32_t i : v > 0 ? polarNorth_ : polarSouth_) visit(i);
    return;
  }
  if (!tree_.contains(u, v)) return;
  const std::span<const std::uint32_t> items = tree_.leafItems(u, v);
  prefetch(items);
  storage = lineAt(u, v), line = &storage;
  for (std::uint32_t i : items) {
    if (inBox(tris_[i], u, v)) visit(i);
  }
}

template <AxialMapping M>
void CurvedIndex<M>::prefetch(std::span<const std::uint32_t> items) const {
  for (std::uint32_t i : items) {
    const char* p = reinterpret_cast<const char*>(&tris_[i]);
    __builtin_prefetch(p);
    __builtin_prefetch(p + 64);
  }
}

template <AxialMapping M>
template <bool Below>
std::uint32_t CurvedIndex<M>::nearestIn(std::span<const std::uint32_t> items, bool checkBox, double u, double v,
                                        const Line& line, double ez, double& hOut, double& tOut) const {
  std::uint32_t best = kNoTriangle;
  double bestE = 0;
  for (std::uint32_t i : items) {
    if (checkBox && !inBox(tris_[i], u, v)) continue;
    double t;
    if (!hits(tris_[i], line, t)) continue;
    const double hh = heightOf(line, t);
    const double e = elevation(hh);
    if (Below ? !(e <= ez) : !(e >= ez)) continue;
    if (best == kNoTriangle || (Below ? e > bestE : e < bestE) ||
        (e == bestE && tris_[i].polygon < tris_[best].polygon)) {
      best = i, bestE = e, hOut = hh, tOut = t;
    }
  }
  return best;
}

template <AxialMapping M>
template <class ZOf>
void CurvedIndex<M>::heightsBelowBatch(std::span<const Point2> points, const ZOf& zOf,
                                       std::span<std::optional<double>> out) const {
  // Software pipelining as in CartesianIndex::heightsBelow: every point's leaf, then every leaf's
  // references, then every leaf's triangles, each stage issuing its loads for the whole group
  // before any is waited for, so the three dependent cache misses of a query overlap.
  constexpr std::size_t kGroup = 16;
  Quadtree::Node leaf[kGroup];
  bool inTree[kGroup];
  double uu[kGroup];
  for (std::size_t g = 0; g < points.size(); g += kGroup) {
    const std::size_t n = std::min(kGroup, points.size() - g);
    for (std::size_t i = 0; i < n; ++i) {
      const Point2 p = points[g + i];
      uu[i] = normalizeU(p.u);
      inTree[i] = std::isfinite(uu[i]) && !polar(p.v) && tree_.contains(uu[i], p.v);
      leaf[i] = inTree[i] ? tree_.leafNode(uu[i], p.v) : Quadtree::Node{0, 0};
      __builtin_prefetch(tree_.leafRange(leaf[i]).data());
    }
    for (std::size_t i = 0; i < n; ++i) prefetch(tree_.leafRange(leaf[i]));
    for (std::size_t i = 0; i < n; ++i) {
      const Point2 p = points[g + i];
      if (!inTree[i]) {
        out[g + i] = this->heightBelow(p.u, p.v, zOf(g + i));  // the poles, off the domain, the invalid
        continue;
      }
      double h = 0, t = 0;
      const Line line = lineAt(uu[i], p.v);
      const std::uint32_t best =
          nearestIn<true>(tree_.leafRange(leaf[i]), true, uu[i], p.v, line, elevation(zOf(g + i)), h, t);
      out[g + i] = best == kNoTriangle ? std::nullopt : std::optional<double>(h);
    }
  }
}

template <AxialMapping M>
void CurvedIndex<M>::batchBelow(std::span<const Point2> points, double z, std::span<std::optional<double>> out) const {
  heightsBelowBatch(
      points, [z](std::size_t) { return z; }, out);
}

template <AxialMapping M>
void CurvedIndex<M>::batchBelow(std::span<const Point2> points, std::span<const double> zs,
                                std::span<std::optional<double>> out) const {
  heightsBelowBatch(
      points, [zs](std::size_t i) { return zs[i]; }, out);
}

template <AxialMapping M>
template <bool Below>
std::uint32_t CurvedIndex<M>::nearest(double u, double v, double h, double& hOut, Line& line, double& tOut,
                                      Cursor* cursor) const {
  // Outside the domain (a latitude beyond the poles) or not finite: no terrain (index.hpp).
  if (!validQuery(u, v) || std::isnan(h)) return kNoTriangle;
  u = normalizeU(u);
  if (polar(v)) {
    line = lineAt(u, v);
    return nearestIn<Below>(v > 0 ? polarNorth_ : polarSouth_, false, u, v, line, elevation(h), hOut, tOut);
  }
  if (!tree_.contains(u, v)) return kNoTriangle;
  // (On a walk, the triangles of a leaf ahead on its course are fetched as it enters a leaf.)
  const std::span<const std::uint32_t> items = tree_.leafRange(
      cursor ? tree_.leafNode(u, v, *cursor, [this](std::span<const std::uint32_t> ahead) { prefetch(ahead); })
             : tree_.leafNode(u, v));
  prefetch(items);  // the candidates load while the line is computed
  line = lineAt(u, v);
  return nearestIn<Below>(items, true, u, v, line, elevation(h), hOut, tOut);
}

template <AxialMapping M>
Hit CurvedIndex<M>::makeHit(std::uint32_t i, const Line& line, double tHit) const {
  const Tri& t = tris_[i];
  const Eigen::Vector3d d(line.d[0], line.d[1], line.d[2]);
  Eigen::Vector3d n = Eigen::Vector3d(t.n[0], t.n[1], t.n[2]).normalized();
  const Eigen::Vector3d up = M::kHeightUp ? d : Eigen::Vector3d(-d);
  if (n.dot(up) < 0) n = -n;
  Hit hit;
  hit.height = heightOf(line, tHit);
  hit.world = mapping_.fromLocal(Eigen::Vector3d(0, 0, line.s) + tHit * d);
  hit.normal = mapping_.directionFromLocal(n);
  hit.polygon = t.polygon;
  return hit;
}

template <AxialMapping M>
template <bool Below>
std::optional<Hit> CurvedIndex<M>::hitAt(double u, double v, double h, Cursor* cursor) const {
  double hh, t;
  Line line;
  const std::uint32_t i = nearest<Below>(u, v, h, hh, line, t, cursor);
  if (i == kNoTriangle) return std::nullopt;
  return makeHit(i, line, t);
}

template <AxialMapping M>
std::optional<double> CurvedIndex<M>::heightAt(double u, double v, double z, Cursor* cursor) const {
  double hh, t;
  Line line;
  if (nearest<true>(u, v, z, hh, line, t, cursor) == kNoTriangle) return std::nullopt;
  return hh;
}

template <AxialMapping M>
std::optional<Hit> CurvedIndex<M>::hitBelow(double u, double v, double h, Cursor* cursor) const {
  return hitAt<true>(u, v, h, cursor);
}

template <AxialMapping M>
std::optional<Hit> CurvedIndex<M>::hitAbove(double u, double v, double h, Cursor* cursor) const {
  return hitAt<false>(u, v, h, cursor);
}

template <AxialMapping M>
std::vector<Hit> CurvedIndex<M>::all(double u, double v) const {
  if (!validQuery(u, v)) return {};
  u = normalizeU(u);
  Line line;
  const Line* lp = nullptr;
  std::vector<Hit> hits_;
  forCandidates(u, v, lp, line, [&](std::uint32_t i) {
    double t;
    if (hits(tris_[i], *lp, t)) hits_.push_back(makeHit(i, *lp, t));
  });
  std::sort(hits_.begin(), hits_.end(), [this](const Hit& a, const Hit& b) {
    const double ea = elevation(a.height), eb = elevation(b.height);
    return ea != eb ? ea > eb : a.polygon < b.polygon;
  });
  return hits_;
}

template <AxialMapping M>
std::vector<LineHit> CurvedIndex<M>::alongLine(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                                               double tmin, double tmax) const {
  std::vector<LineHit> out;
  if (!origin.allFinite() || !direction.allFinite() || direction.squaredNorm() == 0) return out;
  // The line in the local frame; each live triangle tested exactly on its corners' offsets from
  // the line's origin (the sign of det[a - O; b - O; d] per edge, as CartesianIndex::alongLine).
  const Eigen::Vector3d O = mapping_.toLocal(origin);
  // The direction turned, not the difference of two far points (which loses its low digits).
  const Eigen::Vector3d d = mapping_.directionToLocal(direction);
  for (std::uint32_t i = 0; i < tris_.size(); ++i) {
    if (!live(i)) continue;
    const Tri& tri = tris_[i];
    double q[3][3];
    for (int k = 0; k < 3; ++k) {
      for (int c = 0; c < 3; ++c) q[k][c] = tri.p[k][c] - O[c];
    }
    detail::LineCrossing x;
    if (!detail::crossesTriangle(q, d, x) || !(x.t >= tmin && x.t <= tmax)) continue;
    const double tt = x.t;
    const Eigen::Vector3d& n = x.normal;
    LineHit lh;
    lh.t = tt;
    lh.hit.world = origin + tt * direction;
    Eigen::Vector3d m;
    if (!mapped(lh.hit.world, m)) continue;
    lh.hit.height = m.z();
    Eigen::Vector3d normal = mapping_.directionFromLocal(n.normalized());
    if (normal.dot(mapping_.line(m.x(), m.y()).down) > 0) normal = -normal;  // up: against down
    lh.hit.normal = normal;
    lh.hit.polygon = tri.polygon;
    out.push_back(lh);
  }
  std::sort(out.begin(), out.end(),
            [](const LineHit& x, const LineHit& y) { return x.t != y.t ? x.t < y.t : x.hit.polygon < y.hit.polygon; });
  return out;
}

template <AxialMapping M>
std::uint32_t CurvedIndex<M>::testsAt(double u, double v) const {
  u = normalizeU(u);
  if (polar(v)) return static_cast<std::uint32_t>((v > 0 ? polarNorth_ : polarSouth_).size());
  if (!tree_.contains(u, v)) return 0;
  return static_cast<std::uint32_t>(tree_.leafItems(u, v).size());
}

template <AxialMapping M>
void CurvedIndex<M>::rebuildTree(Box2 root) {
  const QuadtreeOptions options = tree_.options();
  const double minU = tree_.minSizeU(), minV = tree_.minSizeV();
  tree_.build(
      static_cast<std::uint32_t>(tris_.size()), root, options,
      [this](std::uint32_t i, const Box2& b) { return live(i) && overlaps(i, b); }, minU, minV);
  stats_.domain = root;
}

template <AxialMapping M>
std::uint32_t CurvedIndex<M>::insertPolygon(std::span<const Eigen::Vector3d> corners) {
  const auto id = static_cast<std::uint32_t>(stats_.polygons);
  if (corners.size() < 3) {
    throw Error("insertPolygon: a polygon needs at least 3 corners, got " + std::to_string(corners.size()));
  }
  std::vector<Eigen::Vector3d> local;
  std::vector<double> heights;
  for (const Eigen::Vector3d& c : corners) {
    local.push_back(mapping_.toLocal(c));
    if (!c.allFinite() || !local.back().allFinite()) {
      throw Error("insertPolygon: a corner is not finite");
    }
    heights.push_back(mapping_.footprintHeight(c));
  }
  for (const auto& p : local) scale_ = std::max(scale_, p.lpNorm<1>());
  ++stats_.polygons;
  stats_.vertices += corners.size();
  const Box2 old = tree_.box();
  Box2 root = old.empty() ? Box2{kInf, kInf, -kInf, -kInf} : old;
  bool grows = old.empty();
  const auto first = static_cast<std::uint32_t>(tris_.size());
  for (std::size_t k = 1; k + 1 < local.size(); ++k) {
    const Eigen::Vector3d p[3] = {local[0], local[k], local[k + 1]};
    const double h[3] = {heights[0], heights[k], heights[k + 1]};
    Tri t;
    FootBox box;
    if (!makeTriangle(p, h, id, t, box)) {
      ++stats_.leftOut;
      continue;
    }
    const auto i = static_cast<std::uint32_t>(tris_.size());
    tris_.push_back(t);
    ledger_.added(id, i);
    ++stats_.triangles;
    addToPolarLists(i, box);
    // Grow the tree's box to the footprint (all of u when it crosses the seam).
    if (box.vlo < root.vlo || box.vhi > root.vhi) grows = true;
    root.vlo = std::min(root.vlo, box.vlo), root.vhi = std::max(root.vhi, box.vhi);
    if (box.uhi > 180.0 || box.ulo < root.ulo || box.uhi > root.uhi) {
      grows = grows || !(root.ulo == -180.0 && root.uhi == 180.0);
      root.ulo = box.uhi > 180.0 ? -180.0 : std::min(root.ulo, box.ulo);
      root.uhi = box.uhi > 180.0 ? 180.0 : std::max(root.uhi, box.uhi);
    }
  }
  if (grows) {
    rebuildTree(root);
  } else {
    for (auto i = first; i < tris_.size(); ++i) {
      tree_.insert(
          i, [this](std::uint32_t j, const Box2& b) { return overlaps(j, b); },
          [](std::span<std::uint32_t>) { return false; });
    }
  }
  treeStatsStale_ = true;
  return id;
}

template <AxialMapping M>
bool CurvedIndex<M>::removePolygon(std::uint32_t polygon) {
  const std::optional<std::size_t> triangles = ledger_.remove(
      polygon, stats_.polygons, tris_.size(), [this](std::size_t i) { return tris_[i].polygon; },
      [this](std::uint32_t i) {
        tree_.remove(i, [this](std::uint32_t j, const Box2& b) { return overlaps(j, b); });
        --stats_.triangles;
      });
  if (!triangles) return false;
  for (auto* list : {&polarNorth_, &polarSouth_}) {
    std::erase_if(*list, [&](std::uint32_t i) { return tris_[i].polygon == polygon; });
  }
  treeStatsStale_ = true;
  return true;
}

template class CurvedIndex<SphericalMapping>;
template class CurvedIndex<CylindricalMapping>;
template class CurvedIndex<GeodeticMapping>;
static_assert(EditableTerrain<SphericalIndex> && EditableTerrain<CylindricalIndex> && EditableTerrain<GeodeticIndex>);

}  // namespace qota
