// ShadowTiles' state (see qota/shadow_tiles.hpp): the pass over the heights written as checked
// text for the jobs of a batch, and read back against the raster it was made for.
#include "qota/shadow_tiles.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <charconv>
#include <cmath>
#include <mutex>
#include <optional>
#include <sstream>

#include "qota/error.hpp"
#include "qota/memory_budget.hpp"
#include "qota/version.hpp"
#include "shadow_tiles_parts.hpp"

namespace qota {

using tiles::kDeg;
using tiles::Local;
using tiles::localAt;

namespace {

// state()'s text: a first line naming the format, then one "name value" a line; numbers in
// hexadecimal floating point (every bit), text as its length and its bytes; last, "checksum" and
// checksumOf everything before that line, so that an edit or damage anywhere is refused.
constexpr const char* kStateMagic = "qota-shadow-tiles";

constexpr int kStateFormat = 3;  // (3: "validPixels", once "validCells")

struct StateWriter {
  std::ostringstream out;
  void number(const char* name, double v) {
    char buffer[64];
    const auto end = std::to_chars(buffer, buffer + sizeof buffer, v, std::chars_format::hex).ptr;
    out << name << ' ' << std::string(buffer, end) << '\n';
  }
  void text(const char* name, const std::string& v) { out << name << ' ' << v.size() << ' ' << v << '\n'; }
  std::string finish() const {
    std::string body = out.str();
    return body + "checksum " + checksumOf(body) + "\n";
  }
};

struct StateReader {
  std::istringstream in;
  [[noreturn]] static void refuse(const std::string& why) { throw Error("a shadow tiles state " + why); }
  void expect(const char* name) {
    std::string got;
    if (!(in >> got) || got != name) refuse(std::string("without its '") + name + "'");
    in.get();
  }
  double number(const char* name) {
    expect(name);
    std::string word;
    in >> word;
    double v = 0;
    const auto [end, ec] = std::from_chars(word.data(), word.data() + word.size(), v, std::chars_format::hex);
    if (ec != std::errc() || end != word.data() + word.size())
      refuse(std::string("with '") + name + "' not a number: " + word);
    return v;
  }
  // A number that must be finite and in [lo, hi] (and whole, when asked).
  double bounded(const char* name, double lo, double hi, bool whole = false) {
    const double v = number(name);
    if (!(v >= lo && v <= hi) || (whole && v != std::floor(v))) {
      refuse(std::string("with '") + name + "' " + std::to_string(v) + ", which no raster gives");
    }
    return v;
  }
  std::string text(const char* name) {
    expect(name);
    std::size_t n = 0;
    if (!(in >> n) || n > ShadowTiles::kMostStateBytes) refuse(std::string("with a bad '") + name + "'");
    in.get();
    std::string v(n, '\0');
    if (!in.read(v.data(), static_cast<std::streamsize>(n))) refuse(std::string("cut in '") + name + "'");
    return v;
  }
};

// The state's text without its checksum line, once that checksum is checked.
std::string checkedStateBody(const std::string& state) {
  const std::string magic = std::string(kStateMagic) + " ";
  if (state.compare(0, magic.size(), magic) != 0)
    throw Error("not a shadow tiles state (no '" + std::string(kStateMagic) + "' line)");
  const std::size_t line = state.rfind("\nchecksum ");
  if (line == std::string::npos) {
    if (state.compare(0, magic.size() + 2, magic + "1\n") == 0) {
      throw Error("a shadow tiles state of an older qota (no checksum); make it again");
    }
    throw Error("a shadow tiles state that was edited, damaged or cut short (no checksum line); make it again");
  }
  std::string body = state.substr(0, line + 1);
  std::string sum = state.substr(line + 10);
  if (!sum.empty() && sum.back() == '\n') sum.pop_back();
  if (sum != checksumOf(body)) {
    throw Error(
        "a shadow tiles state that was edited or damaged (its checksum does not match its text); make it again");
  }
  return body;
}

std::string shortest(double v) {
  char buffer[64];
  return std::string(buffer, std::to_chars(buffer, buffer + sizeof buffer, v).ptr);
}

std::string nodataText(const std::optional<double>& nodata) {
  if (!nodata) return "none";
  char buffer[64];
  return std::string(buffer, std::to_chars(buffer, buffer + sizeof buffer, *nodata, std::chars_format::hex).ptr);
}

}  // namespace

std::string ShadowTiles::state() const {
  StateWriter w;
  w.out << kStateMagic << ' ' << kStateFormat << '\n';
  const DemTerrain& d = basis_.raster;
  const LocalFrame& f = basis_.shared;
  w.text("qota", QOTA_VERSION_STRING);
  w.text("path", d.path);
  w.number("width", d.width), w.number("height", d.height);
  for (double g : d.geotransform) w.number("gt", g);
  w.text("crs", d.crsWkt);
  w.number("band", d.band);
  w.text("nodata", nodataText(d.nodata));
  w.text("unit", d.verticalUnit.name);
  w.number("metresPerUnit", d.verticalUnit.metresPerUnit);
  w.number("flat", basis_.options.flat), w.number("pixelSize", basis_.options.pixelSize);
  w.number("zFactor", basis_.options.zFactor), w.number("scale", basis_.options.scale);
  w.text("heightRefAsked", basis_.options.heightRef);
  w.text("verticalCrs", d.verticalReference.name);
  w.number("verticalEpsg", d.verticalReference.epsg);
  w.number("verticalEllipsoidal", d.verticalReference.ellipsoidal), w.number("earth", d.verticalReference.earth);
  w.text("heightRef", basis_.heightRef.name);
  w.number("minHeight", f.minHeight), w.number("maxHeight", f.maxHeight);
  w.number("pixelSizeX", f.pixelSizeX), w.number("pixelSizeY", f.pixelSizeY);
  w.number("lowest", f.body.lowest), w.number("winding", f.gridWinding);
  w.number("slack", slack_), w.number("validPixels", static_cast<double>(validPixels_));
  w.number("blockSide", blocks_.side());
  std::string hashes;
  hashes.reserve(blocks_.hashes().size() * 16);
  for (std::uint64_t h : blocks_.hashes()) hashes += hexOf(h);
  w.text("blocks", hashes);
  // The blocks' height ranges (in the raster's unit): what plans a tile's window before reading it.
  const auto numbers = [](const std::vector<double>& values) {
    std::string out;
    char buffer[64];
    for (double v : values) {
      out.append(buffer, std::to_chars(buffer, buffer + sizeof buffer, v, std::chars_format::hex).ptr);
      out += ' ';
    }
    return out;
  };
  w.text("blockLows", numbers(blocks_.lows()));
  w.text("blockHighs", numbers(blocks_.highs()));
  return w.finish();
}

ShadowTiles ShadowTiles::restore(const std::string& state) {
  if (state.size() > kMostStateBytes)
    throw Error("a shadow tiles state of " + std::to_string(state.size()) + " bytes: larger than any");
  StateReader r{std::istringstream(checkedStateBody(state))};
  std::string magic;
  int format = 0;
  if (!(r.in >> magic >> format) || magic != kStateMagic || format != kStateFormat) {
    throw Error("a shadow tiles state of another format (" + std::to_string(format) + ", this qota reads " +
                std::to_string(kStateFormat) + "); make it again");
  }
  const std::string version = r.text("qota");
  if (version != QOTA_VERSION_STRING) {
    throw Error("a shadow tiles state made by qota " + version + ", not this qota " + QOTA_VERSION_STRING +
                "; make it again");
  }
  constexpr double kInt = 2147483647.0;
  DemTerrain d;
  d.path = r.text("path");
  d.width = static_cast<int>(r.bounded("width", 1, kInt, true));
  d.height = static_cast<int>(r.bounded("height", 1, kInt, true));
  for (double& g : d.geotransform) g = r.bounded("gt", -1e300, 1e300);
  const auto& g = d.geotransform;
  if (!(g[1] * g[5] - g[2] * g[4] != 0)) StateReader::refuse("with a geotransform without area");
  d.crsWkt = r.text("crs");
  d.band = static_cast<int>(r.bounded("band", 1, kInt, true));
  const std::string nodata = r.text("nodata");
  if (nodata != "none") {
    double v = 0;
    const auto [end, ec] = std::from_chars(nodata.data(), nodata.data() + nodata.size(), v, std::chars_format::hex);
    if (ec != std::errc() || end != nodata.data() + nodata.size())
      StateReader::refuse("with a nodata value that is not a number");
    d.nodata = v;
  }
  d.verticalUnit.name = r.text("unit");
  d.verticalUnit.metresPerUnit = r.bounded("metresPerUnit", 1e-12, 1e12);
  FrameOptions o;
  o.flat = r.bounded("flat", 0, 1, true) != 0;
  o.pixelSize = r.bounded("pixelSize", 0, 1e300);
  o.zFactor = r.bounded("zFactor", -1e300, 1e300), o.scale = r.bounded("scale", 0, 1e300);
  o.heightRef = r.text("heightRefAsked");
  d.verticalReference.name = r.text("verticalCrs");
  d.verticalReference.epsg = static_cast<int>(r.bounded("verticalEpsg", 0, kInt, true));
  d.verticalReference.ellipsoidal = r.bounded("verticalEllipsoidal", 0, 1, true) != 0;
  d.verticalReference.earth = r.bounded("earth", 0, 1, true) != 0;
  const std::string heightRef = r.text("heightRef");
  ShadowTiles t;
  t.basis_ = frameBasis(d, o);
  if (t.basis_.heightRef.name != heightRef) {
    throw Error("a shadow tiles state made over the " + heightRef + ", which is the " + t.basis_.heightRef.name +
                " here; make it again");
  }
  LocalFrame& f = t.basis_.shared;
  f.minHeight = r.number("minHeight"), f.maxHeight = r.number("maxHeight");
  f.pixelSizeX = r.bounded("pixelSizeX", 1e-300, 1e300), f.pixelSizeY = r.bounded("pixelSizeY", 1e-300, 1e300);
  f.body.lowest = r.bounded("lowest", -1e300, 1e300);
  f.gridWinding = static_cast<int>(r.bounded("winding", -1, 1, true));
  t.slack_ = r.bounded("slack", 0, 360);
  const double pixels = static_cast<double>(d.width) * d.height;
  t.validPixels_ = static_cast<std::uint64_t>(r.bounded("validPixels", 0, pixels, true));
  // The height range: finite and in order when the raster has data (the pass's +inf/-inf else).
  if (f.gridWinding == 0 || (t.validPixels_ > 0 && !(std::isfinite(f.minHeight) && std::isfinite(f.maxHeight) &&
                                                     f.minHeight <= f.maxHeight))) {
    StateReader::refuse("with a height range or winding that no raster gives");
  }
  const int side = static_cast<int>(r.bounded("blockSide", 64, kInt, true));
  const std::string hex = r.text("blocks");
  if (hex.size() % 16 != 0) StateReader::refuse("with a cut block hash");
  std::vector<std::uint64_t> hashes(hex.size() / 16);
  for (std::size_t k = 0; k < hashes.size(); ++k) {
    const char* first = hex.data() + 16 * k;
    const auto [end, ec] = std::from_chars(first, first + 16, hashes[k], 16);
    if (ec != std::errc() || end != first + 16) StateReader::refuse("with a block hash that is not hexadecimal");
  }
  try {
    t.blocks_ = HeightBlocks(d.width, d.height, side, std::move(hashes));
  } catch (const Error& e) {
    StateReader::refuse(std::string("with ") + e.what());
  }
  if (t.blocks_.side() != HeightBlocks(d.width, d.height).side()) StateReader::refuse("with blocks of another size");
  const auto numbers = [](const std::string& text) {
    std::vector<double> out;
    const char* p = text.data();
    const char* end = p + text.size();
    while (p < end) {
      double v = 0;
      const auto [next, ec] = std::from_chars(p, end, v, std::chars_format::hex);
      if (ec != std::errc() || next == end || *next != ' ')
        StateReader::refuse("with a block height range that is not numbers");
      out.push_back(v);
      p = next + 1;
    }
    return out;
  };
  std::vector<double> lows = numbers(r.text("blockLows"));  // (in this order: the text's)
  std::vector<double> highs = numbers(r.text("blockHighs"));
  try {
    t.blocks_.setRanges(std::move(lows), std::move(highs));
  } catch (const Error& e) {
    StateReader::refuse(std::string("with ") + e.what());
  }
  t.basis_.complete = true;
  return t;
}

ShadowTiles ShadowTiles::restore(const std::string& state, const std::string& path, const DemOptions& dem,
                                 const FrameOptions& frame) {
  ShadowTiles t = restore(state);
  auto source = std::make_unique<Source>();
  source->windows = std::make_unique<DemWindows>(path, dem);
  const DemWindows* windows = source->windows.get();
  const DemTerrain& d = windows->dem();
  const DemTerrain& was = t.basis_.raster;
  const FrameOptions& o = t.basis_.options;
  const auto refuse = [&](const std::string& field, const std::string& state, const std::string& now) {
    throw Error(path + ": not the raster of the shadow tiles' state (made from " + was.path + "): its " + field +
                " differs (the state's " + state + ", this raster's " + now + ")");
  };
  const auto size = [](const DemTerrain& r) { return std::to_string(r.width) + " x " + std::to_string(r.height); };
  const auto gt = [](const DemTerrain& r) {
    std::string out;
    for (double v : r.geotransform) out += (out.empty() ? "" : ",") + shortest(v);
    return out;
  };
  const auto nodata = [](const DemTerrain& r) { return r.nodata ? shortest(*r.nodata) : std::string("none"); };
  if (d.width != was.width || d.height != was.height) refuse("size", size(was), size(d));
  if (d.geotransform != was.geotransform) refuse("geotransform", gt(was), gt(d));
  if (d.crsWkt != was.crsWkt)
    refuse("CRS", "'" + was.crsWkt.substr(0, 60) + "...'", "'" + d.crsWkt.substr(0, 60) + "...'");
  if (d.band != was.band) refuse("band", std::to_string(was.band), std::to_string(d.band));
  if (d.nodata.has_value() != was.nodata.has_value() ||
      (d.nodata && !(*d.nodata == *was.nodata || (std::isnan(*d.nodata) && std::isnan(*was.nodata))))) {
    refuse("nodata value", nodata(was), nodata(d));
  }
  if (d.verticalUnit.name != was.verticalUnit.name || d.verticalUnit.metresPerUnit != was.verticalUnit.metresPerUnit) {
    refuse("vertical unit", "'" + was.verticalUnit.name + "'", "'" + d.verticalUnit.name + "'");
  }
  const auto option = [&](const char* name, double state, double now) {
    if (state != now) {
      throw Error(path + ": the shadow tiles' state was made with other frame options (" + name + " " +
                  shortest(state) + ", this run " + shortest(now) + "); give the same, or another state file");
    }
  };
  option("--flat", o.flat, frame.flat);
  option("--pixel-size", o.pixelSize, frame.pixelSize);
  option("-z", o.zFactor, frame.zFactor);
  option("-s", o.scale, frame.scale);
  if (frame.heightRef != o.heightRef) {
    throw Error(path + ": the shadow tiles' state was made with other frame options (--height-ref '" + o.heightRef +
                "', this run '" + frame.heightRef + "'); give the same, or another state file");
  }
  if (d.verticalReference.name != was.verticalReference.name ||
      d.verticalReference.epsg != was.verticalReference.epsg ||
      d.verticalReference.ellipsoidal != was.verticalReference.ellipsoidal) {
    refuse("vertical CRS", "'" + was.verticalReference.name + "'", "'" + d.verticalReference.name + "'");
  }
  source->reader = [windows](const PixelWindow& w, std::vector<double>& out) {
    windows->read(w.col, w.row, w.width, w.height, out);
  };
  t.source_ = std::move(source);
  t.basis_.raster.path = d.path;
  return t;
}

}  // namespace qota
