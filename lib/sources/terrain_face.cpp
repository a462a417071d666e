// A terrain in its source's own coordinates (see qota/terrain_face.hpp).
#include "qota/terrain_face.hpp"

#include <cmath>
#include <limits>

#include "qota/batch.hpp"
#include "qota/error.hpp"
#include "qota/mapping_registry.hpp"

namespace qota {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

}  // namespace

Terrain Terrain::open(const SourceOptions& options) { return Terrain(openIndex(options)); }

Terrain::Terrain(TreeFile tree) : index_(std::move(tree.index)), source_(std::move(tree.source)) {
  const std::string& where = source_.path;
  // How the index's (u, v, h) meet the source's coordinates:
  //   cartesian: the index works relative to an origin near the data, for precision (an exact
  //     subtraction; heights stay in the source's unit);
  //   geodetic: the index's h is metres along the normal over the ellipsoid; the source's are in
  //     its vertical unit over its reference (a geoid's undulation added);
  //   spherical, cylindrical: metres (the radius, the distance from the axis) on both sides.
  //   enu: metres in the frame on both sides.
  // The registry's entry says which (a type test here would miss a new mapping).
  const MappingEntry& entry = mappingEntry(mappingNameOf(index_));
  if (entry.map) {
    std::visit(
        [&](const auto& index) {
          if constexpr (requires {
                          index.mapping().origin().x();
                          index.mapping().vertical();
                        }) {
            if (!index.mapping().vertical()) {
              throw Error(where + ": a Cartesian terrain with tilted gravity has no map coordinates (query its index)");
            }
            const Eigen::Vector3d o = index.mapping().origin();
            du_ = o.x(), dv_ = o.y(), dh_ = o.z();
          }
        },
        index_);
  }
  if (entry.ellipsoidHeights) {
    const double m = source_.metresPerUnit;
    scale_ = m > 0 && std::isfinite(m) ? m : 1.0;
    if (!source_.geoidGrid.empty()) {
      geoid_ = std::make_shared<const Geoid>(storedHeightReference(source_.heightRef, source_.geoidGrid));
    }
  }
  longitudes_ = entry.lonLat;
  // A raster's footprint where a query's (x, y) are the raster's own coordinates (a map; lon/lat
  // on the ellipsoid): the outer half-pixel rule, as `qota sample` keeps it.
  const bool map = entry.map || (entry.lonLat && entry.ellipsoid);
  if (map && source_.width > 0 && source_.height > 0) {
    DemTerrain grid;
    grid.width = source_.width, grid.height = source_.height;
    grid.geotransform = source_.geotransform;
    grid.lonLat = crsIsGeographic(source_.crsWkt) && grid.geotransform[2] == 0 && grid.geotransform[4] == 0;
    footprint_ = std::move(grid);
    inverse_ = footprint_->inverseGeotransform();
  }
}

std::string Terrain::heightRef() const {
  if (!mappingEntry(mappingNameOf(index_)).ellipsoidHeights) return "";
  return source_.geoidGrid.empty() && source_.heightRef.empty() ? "ellipsoid" : source_.heightRef;
}

Point2 Terrain::mapped(double x, double y) const {
  if (footprint_) {
    const auto p = footprint_->surfacePoint(x, y, inverse_);
    if (!p) return {kNaN, kNaN};
    x = (*p)[0], y = (*p)[1];
  }
  Point2 q{x - du_, y - dv_};
  if (longitudes_) q.u -= 360.0 * std::floor((q.u + 180.0) / 360.0);  // the index's [-180, 180)
  return q;
}

double Terrain::toIndex(double z, const Point2& at, int side) const {
  const double h = (z - dh_) * scale_ + (geoid_ ? geoid_->undulation(at.u, at.v) : 0.0);
  return geoid_ && side ? h + side * std::fabs(h) * 8 * std::numeric_limits<double>::epsilon() : h;
}

double Terrain::fromIndex(double h, const Point2& at) const {
  return (h - (geoid_ ? geoid_->undulation(at.u, at.v) : 0.0)) / scale_ + dh_;
}

std::optional<double> Terrain::height(double x, double y) const {
  const Point2 q = mapped(x, y);
  const auto hit = std::visit([&](const auto& index) { return index.top(q.u, q.v); }, index_);
  return hit ? std::optional(fromIndex(hit->height, q)) : std::nullopt;
}

std::optional<double> Terrain::below(double x, double y, double z) const {
  const Point2 q = mapped(x, y);
  const auto hit = std::visit([&](const auto& index) { return index.below(q.u, q.v, toIndex(z, q, 1)); }, index_);
  return hit ? std::optional(fromIndex(hit->height, q)) : std::nullopt;
}

std::optional<double> Terrain::above(double x, double y, double z) const {
  const Point2 q = mapped(x, y);
  const auto hit = std::visit([&](const auto& index) { return index.above(q.u, q.v, toIndex(z, q, -1)); }, index_);
  return hit ? std::optional(fromIndex(hit->height, q)) : std::nullopt;
}

bool Terrain::normalsMetric() const {
  return !(mappingEntry(mappingNameOf(index_)).map && crsIsGeographic(source_.crsWkt));
}

std::vector<Hit> Terrain::all(double x, double y) const {
  const Point2 q = mapped(x, y);
  std::vector<Hit> hits = std::visit([&](const auto& index) { return index.all(q.u, q.v); }, index_);
  for (Hit& h : hits) h.height = fromIndex(h.height, q);
  return hits;
}

namespace {

// The points (and heights) into the index's frame, run(index, points, zs, out) on every core,
// the answers back: the batch's shape for every query.
template <class Run>
void inBatch(const Terrain& t, std::span<const double> x, std::span<const double> y, std::span<const double> z,
             int side, std::span<double> out, Run&& run) {
  const std::size_t n = x.size();
  if (y.size() != n || out.size() != n || (!z.empty() && z.size() != n)) {
    throw Error("a batch of " + std::to_string(n) + " points with " + std::to_string(y.size()) + " y, " +
                std::to_string(z.size()) + " z and room for " + std::to_string(out.size()) + " answers");
  }
  std::vector<Point2> pts(n);
  std::vector<double> zs(z.size());
  std::vector<std::optional<double>> answers(n);
  batch::inSlices(n, 0, 1 << 15, [&](std::size_t lo, std::size_t hi) {
    for (std::size_t i = lo; i < hi; ++i) pts[i] = t.mapped(x[i], y[i]);
    for (std::size_t i = lo; !z.empty() && i < hi; ++i) zs[i] = t.toIndex(z[i], pts[i], side);
  });
  std::visit(
      [&](const auto& index) {
        run(index, std::span<const Point2>(pts), std::span<const double>(zs), std::span(answers));
      },
      t.index());
  batch::inSlices(n, 0, 1 << 15, [&](std::size_t lo, std::size_t hi) {
    for (std::size_t i = lo; i < hi; ++i) out[i] = answers[i] ? t.fromIndex(*answers[i], pts[i]) : kNaN;
  });
}

}  // namespace

void Terrain::heights(std::span<const double> x, std::span<const double> y, std::span<double> out) const {
  inBatch(*this, x, y, {}, 0, out,
          [](const auto& index, auto pts, auto, auto answers) { index.heightsParallel(pts, answers); });
}

void Terrain::below(std::span<const double> x, std::span<const double> y, std::span<const double> z,
                    std::span<double> out) const {
  if (z.size() != x.size()) throw Error("below: one z a point");
  inBatch(*this, x, y, z, 1, out,
          [](const auto& index, auto pts, auto zs, auto answers) { index.heightsBelowParallel(pts, zs, answers); });
}

void Terrain::above(std::span<const double> x, std::span<const double> y, std::span<const double> z,
                    std::span<double> out) const {
  if (z.size() != x.size()) throw Error("above: one z a point");
  inBatch(*this, x, y, z, -1, out, [](const auto& index, auto pts, auto zs, auto answers) {
    batch::inSlices(pts.size(), 0, 4096, [&](std::size_t lo, std::size_t hi) {
      for (std::size_t i = lo; i < hi; ++i) {
        const auto hit = index.above(pts[i].u, pts[i].v, zs[i]);
        answers[i] = hit ? std::optional(hit->height) : std::nullopt;
      }
    });
  });
}

}  // namespace qota
