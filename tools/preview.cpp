#include "preview.hpp"

#include <Eigen/Geometry>
#include <cairo.h>

#include <algorithm>
#include <cmath>
#include <memory>

#include "qota/error.hpp"
#include "text_output.hpp"

namespace qota::tools {

double hillshadeAt(const LocalFrame& f, int c, int r, const Eigen::Vector3d& light) {
  const int w = f.width, h = f.height;
  const auto at = [&](int cc, int rr) -> const Eigen::Vector3d& {
    return f.mesh.vertices[static_cast<std::size_t>(std::clamp(rr, 0, h - 1)) * w + std::clamp(cc, 0, w - 1)];
  };
  const Eigen::Vector3d n = (at(c + 1, r) - at(c - 1, r)).cross(at(c, r - 1) - at(c, r + 1));
  return n.squaredNorm() > 0 && std::isfinite(n.squaredNorm()) ? std::max(0.0, n.normalized().dot(light)) : 0.5;
}

std::vector<double> hillshade(const LocalFrame& f, const Eigen::Vector3d& light) {
  std::vector<double> shade(f.pixelCount(), -1.0);
  for (int r = 0; r < f.height; ++r) {
    for (int c = 0; c < f.width; ++c) {
      const std::size_t i = static_cast<std::size_t>(r) * f.width + c;
      if (f.valid[i]) shade[i] = hillshadeAt(f, c, r, light);
    }
  }
  return shade;
}

namespace {

using Surface = std::unique_ptr<cairo_surface_t, decltype(&cairo_surface_destroy)>;
using Context = std::unique_ptr<cairo_t, decltype(&cairo_destroy)>;

constexpr int kLegendHeight = 46, kMinWidth = 360;

// The picture, and a white strip below it for the legend, drawn on.
struct Canvas {
  Surface surface{nullptr, cairo_surface_destroy};
  Context cr{nullptr, cairo_destroy};
  int width = 0, height = 0, pictureHeight = 0;

  Canvas(int w, int h) : width(std::max(w, kMinWidth)), height(h + kLegendHeight), pictureHeight(h) {
    surface.reset(cairo_image_surface_create(CAIRO_FORMAT_ARGB32, width, height));
    if (cairo_surface_status(surface.get()) != CAIRO_STATUS_SUCCESS) {
      throw Error("cannot make a preview of " + std::to_string(w) + " x " + std::to_string(h) + " pixels");
    }
    cr.reset(cairo_create(surface.get()));
    cairo_set_source_rgb(cr.get(), 1, 1, 1);
    cairo_rectangle(cr.get(), 0, h, width, kLegendHeight);
    cairo_fill(cr.get());
    cairo_select_font_face(cr.get(), "DejaVu Sans", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);
    cairo_set_font_size(cr.get(), 11);
  }
  // Pixel (c, r) of the picture, premultiplied ARGB (alpha 0: no data).
  void pixels(int w, int h, auto&& colourOf) {
    cairo_surface_flush(surface.get());
    unsigned char* data = cairo_image_surface_get_data(surface.get());
    const int stride = cairo_image_surface_get_stride(surface.get());
    for (int r = 0; r < h; ++r) {
      auto* row = reinterpret_cast<std::uint32_t*>(data + static_cast<std::ptrdiff_t>(r) * stride);
      for (int c = 0; c < w; ++c) {
        Colour k;
        row[c] = colourOf(static_cast<std::size_t>(r) * w + c, k)
                     ? 0xff000000u | (std::uint32_t(k.r) << 16) | (std::uint32_t(k.g) << 8) | k.b
                     : 0u;
      }
    }
    cairo_surface_mark_dirty(surface.get());
  }
  void text(double x, double y, const std::string& s) const {
    cairo_set_source_rgb(cr.get(), 0.1, 0.1, 0.1);
    cairo_move_to(cr.get(), x, y);
    cairo_show_text(cr.get(), s.c_str());
  }
  double textWidth(const std::string& s) const {
    cairo_text_extents_t e;
    cairo_text_extents(cr.get(), s.c_str(), &e);
    return e.x_advance;
  }
  void fill(double x, double y, double w, double h, Colour k) const {
    cairo_set_source_rgb(cr.get(), k.r / 255.0, k.g / 255.0, k.b / 255.0);
    cairo_rectangle(cr.get(), x, y, w, h);
    cairo_fill(cr.get());
  }
  void swatch(double x, double y, double w, double h, Colour k) const {
    cairo_set_source_rgb(cr.get(), k.r / 255.0, k.g / 255.0, k.b / 255.0);
    cairo_rectangle(cr.get(), x, y, w, h);
    cairo_fill_preserve(cr.get());
    cairo_set_source_rgb(cr.get(), 0.3, 0.3, 0.3);
    cairo_set_line_width(cr.get(), 0.5);
    cairo_stroke(cr.get());
  }
  void write(const std::string& path, OutputStage& stage) const {
    cairo_surface_flush(surface.get());
    const std::string staged = stage.stage(path).string();
    if (cairo_surface_write_to_png(surface.get(), staged.c_str()) != CAIRO_STATUS_SUCCESS) {
      throw Error(path + ": cannot write the preview");
    }
  }
};

Colour blend(double grey, Colour k, double tint) {
  const auto mix = [&](std::uint8_t c) {
    return static_cast<std::uint8_t>(std::clamp((1 - tint) * grey + tint * c * (0.45 + 0.55 * grey / 255), 0.0, 255.0));
  };
  return {mix(k.r), mix(k.g), mix(k.b)};
}

double greyOf(double shade) { return 60 + 195 * std::clamp(shade, 0.0, 1.0); }

// A perceptually ordered ramp (viridis' stops), t in [0, 1].
Colour ramp(double t) {
  static const Colour stops[] = {{68, 1, 84}, {59, 82, 139}, {33, 145, 140}, {94, 201, 98}, {253, 231, 37}};
  t = std::clamp(std::isfinite(t) ? t : 0.0, 0.0, 1.0) * 4;
  const int i = std::min(3, static_cast<int>(t));
  const double u = t - i;
  const auto mix = [&](std::uint8_t a, std::uint8_t b) {
    return static_cast<std::uint8_t>(std::lround(a + (b - a) * u));
  };
  return {mix(stops[i].r, stops[i + 1].r), mix(stops[i].g, stops[i + 1].g), mix(stops[i].b, stops[i + 1].b)};
}

// Round steps for a scale from lo to hi: 1, 2 or 5 times a power of ten, about 5 of them.
double niceStep(double span) {
  if (!(span > 0)) return 1;
  const double raw = span / 5, p = std::pow(10.0, std::floor(std::log10(raw)));
  return raw / p < 1.5 ? p : raw / p < 3.5 ? 2 * p : raw / p < 7.5 ? 5 * p : 10 * p;
}

}  // namespace

void writeCategoryPreview(const std::string& path, int width, int height, const std::vector<double>& shade,
                          const std::vector<int>& classes, const std::vector<Category>& categories,
                          const std::string& title, OutputStage& stage) {
  Canvas canvas(width, height);
  canvas.pixels(width, height, [&](std::size_t i, Colour& k) {
    const int c = classes[i];
    if (c < 0 || shade[i] < 0) return false;
    k = blend(greyOf(shade[i]), categories[static_cast<std::size_t>(c)].colour,
              categories[static_cast<std::size_t>(c)].tint);
    return true;
  });
  double x = 8;
  const double y = canvas.pictureHeight + 8;
  for (const Category& c : categories) {
    canvas.swatch(x, y, 14, 12, blend(greyOf(0.8), c.colour, c.tint));
    canvas.text(x + 18, y + 10, c.name);
    x += 18 + canvas.textWidth(c.name) + 16;
  }
  canvas.text(8, canvas.pictureHeight + 36, title);
  canvas.write(path, stage);
}

void writeRampPreview(const std::string& path, int width, int height, const std::vector<double>& shade,
                      const std::vector<double>& values, double lo, double hi, const std::string& unit,
                      const std::string& title, OutputStage& stage) {
  if (!(hi > lo)) hi = lo + 1;
  Canvas canvas(width, height);
  canvas.pixels(width, height, [&](std::size_t i, Colour& k) {
    if (!std::isfinite(values[i]) || shade[i] < 0) return false;
    k = blend(greyOf(shade[i]), ramp((values[i] - lo) / (hi - lo)), 0.75);
    return true;
  });
  // The scale: the ramp in a bar, ticks at round values, labelled.
  const double x0 = 8, x1 = std::min(canvas.width - 60.0, 8 + 300.0), y = canvas.pictureHeight + 6;
  for (int px = 0; px < static_cast<int>(x1 - x0); ++px) {
    canvas.fill(x0 + px, y, 1, 10, ramp(px / (x1 - x0 - 1)));
  }
  const double step = niceStep(hi - lo);
  for (double v = std::ceil(lo / step) * step; v <= hi + step * 1e-9; v += step) {
    const double x = x0 + (v - lo) / (hi - lo) * (x1 - x0);
    const std::string label = formatReadable(std::abs(v) < step * 1e-9 ? 0.0 : v, step < 1 ? 1 : 0);
    canvas.fill(x - 0.5, y + 10, 1, 3, {40, 40, 40});
    canvas.text(x - canvas.textWidth(label) / 2, y + 23, label);
  }
  canvas.text(x1 + 6, y + 10, unit);
  canvas.text(8, canvas.pictureHeight + 40, title);
  canvas.write(path, stage);
}

}  // namespace qota::tools
