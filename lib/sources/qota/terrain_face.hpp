// A terrain as users hold it: made from a raster, a mesh or a tree file in any mapping, answering
// points in the source's own coordinates, single and batched, with the index underneath for
// those who want mapped coordinates.
//
// The index works in its mapping's (u, v, h): a raster in the Cartesian mapping is indexed
// relative to its centre (so that UTM coordinates in the millions keep every digit), heights on
// an ellipsoid are metres over it. This face hides that: x, y are a raster's map coordinates in
// its CRS (a mesh's own x, y; longitude, latitude on a body; angle, axial in a station), and
// heights are the source's own: its vertical unit and its vertical reference (a geoid's
// undulation taken off, qota/geoid.hpp). Points follow the rules of `qota sample`: the outer half
// pixel answers as the nearest point on the outermost pixel centres' lines, a longitude names a
// meridian at any turn, and a point off the source's footprint (or not a point) has no terrain,
// as a hole has none.
//
// What a query returns is within the index's accuracy of the exact surface (qota/index.hpp),
// plus the rounding of the conversions here (a subtraction and a scale: a few units in the last
// place). Queries are const and may run on any number of threads at once.
#pragma once

#include <optional>
#include <span>
#include <string>
#include <vector>

#include "qota/geoid.hpp"
#include "qota/source.hpp"
#include "qota/treefile.hpp"

namespace qota {

class Terrain {
 public:
  /// From a raster, a mesh or a tree file (openIndex's rules: SourceOptions says the mapping, band,
  /// radius, height reference). Throws qota::Error.
  static Terrain open(const SourceOptions& options);
  /// From an index and where it came from (a tree file, or what openIndex gave). Throws
  /// qota::Error for an index the face has no source coordinates for (a Cartesian frame whose
  /// gravity is not vertical).
  explicit Terrain(TreeFile tree);

  /// The topmost terrain at (x, y); the nearest at or below z; at or above z.
  std::optional<double> height(double x, double y) const;
  std::optional<double> below(double x, double y, double z) const;
  std::optional<double> above(double x, double y, double z) const;
  /// Every surface on the line of (x, y), topmost first: heights in the source's terms, the rest as
  /// the index gives it (polygon id, unit normal in the world frame; see normalsMetric).
  std::vector<Hit> all(double x, double y) const;
  /// Whether the world frame's axes share one unit, so that a normal is a direction in space: false
  /// for a lon/lat raster in the cartesian mapping (x, y in degrees, heights in metres), whose
  /// normals are unit vectors of that mixed frame (Python refuses them there).
  bool normalsMetric() const;
  /// The same in batches, on every core: out[i] for (x[i], y[i] (, z[i])), NaN for no terrain.
  void heights(std::span<const double> x, std::span<const double> y, std::span<double> out) const;
  void below(std::span<const double> x, std::span<const double> y, std::span<const double> z,
             std::span<double> out) const;
  void above(std::span<const double> x, std::span<const double> y, std::span<const double> z,
             std::span<double> out) const;

  const AnyIndex& index() const { return index_; }
  const TreeSource& source() const { return source_; }
  const char* mapping() const { return mappingNameOf(index_); }
  /// What the heights are over: "ellipsoid" or the geoid as described (geodetic); "" elsewhere.
  std::string heightRef() const;

  /// The face's conversions, for callers that drive the index themselves: the index's (u, v) of a
  /// point ({NaN, NaN} off the terrain), and a height to the index's h and back at that (u, v).
  /// side: +1 for a height asked "at or below", -1 for "at or above" (over a geoid, z + N - N is
  /// not z to the last bit: it is widened by a few units in the last place toward that side, so that
  /// a height answered and asked again finds its own surface), 0 for neither.
  Point2 mapped(double x, double y) const;
  double toIndex(double z, const Point2& at, int side = 0) const;
  double fromIndex(double h, const Point2& at) const;

 private:
  AnyIndex index_;
  TreeSource source_;
  double du_ = 0, dv_ = 0, dh_ = 0, scale_ = 1;  ///< u = x - du, v = y - dv, h = (z - dh) scale
  bool longitudes_ = false;                      ///< u is a longitude: [-180, 180) in the index
  std::shared_ptr<const Geoid> geoid_;           ///< geodetic: the heights' geoid
  std::optional<DemTerrain> footprint_;          ///< a raster's, for the outer half pixel
  std::array<double, 6> inverse_{};              ///< its inverse geotransform
};

}  // namespace qota
