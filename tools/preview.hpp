// PNG previews people can read: the tools' results in colour over a hillshade of the DEM, with a
// legend (named swatches, or a colour ramp with a labelled scale), drawn with Cairo. Internal to
// the tools.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "qota/atomic_file.hpp"
#include "qota/shadow_frame.hpp"

namespace qota::tools {

// Lambertian shade of each pixel of the frame lit from `light` (frame coordinates, unit), in
// [0, 1], from the central differences of its neighbours' positions (clamped at the edges); -1
// where the DEM has no height. hillshadeAt: one pixel's (0.5 where its normal is undefined).
std::vector<double> hillshade(const LocalFrame& f, const Eigen::Vector3d& light);
double hillshadeAt(const LocalFrame& f, int c, int r, const Eigen::Vector3d& light);

struct Colour {
  std::uint8_t r = 0, g = 0, b = 0;
};

// A category of a preview: its colour over the hillshade, and its name in the legend.
struct Category {
  std::string name;
  Colour colour;
  double tint = 0.55;  // how much of the colour (the rest is the hillshade's grey)
};

// Pixels of `classes` (an index into `categories`, or -1 for no data: transparent) over the
// shade, with a legend of the categories and a title below the picture.
void writeCategoryPreview(const std::string& path, int width, int height, const std::vector<double>& shade,
                          const std::vector<int>& classes, const std::vector<Category>& categories,
                          const std::string& title, OutputStage& stage);

// Pixels of `values` (NaN: no data, transparent) on a colour ramp from `lo` to `hi` over the
// shade, with a scale bar labelled in `unit` and a title below the picture.
void writeRampPreview(const std::string& path, int width, int height, const std::vector<double>& shade,
                      const std::vector<double>& values, double lo, double hi, const std::string& unit,
                      const std::string& title, OutputStage& stage);

}  // namespace qota::tools
