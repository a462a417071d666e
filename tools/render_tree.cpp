// qota render-tree: the quadtree's leaves over a faint hillshade (see qota_tools.hpp).
#include <Eigen/Geometry>
#include <cpl_conv.h>
#include <cpl_error.h>
#include <cpl_vsi.h>
#include <gdal_priv.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cctype>
#include <cmath>
#include <cerrno>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <iostream>
#include <memory>
#include <system_error>

#include "qota/dem.hpp"
#include "qota/error.hpp"
#include "qota/mapping_registry.hpp"
#include "qota/treefile.hpp"
#include "qota/shadow.hpp"
#include "preview.hpp"
#include "qota_tools.hpp"
#include "text_output.hpp"

namespace qota::tools {
namespace {

constexpr int kMinSize = 16, kMaxSize = 16384;
// The picture's grey levels (see RenderTreeOptions): the fill of an empty leaf, of a leaf with
// Maxpoly polygons or more, the edge lines, and how much the hillshade may darken a fill.
constexpr double kEmptyGrey = 255, kFullGrey = 160, kShadeDepth = 0.35;
constexpr std::uint8_t kEdgeGrey = 40;

// The node drawn at mapped (u, v): the leaf there, or its ancestor at `depth`; an index into
// tree.nodes(), or -1 outside the root box.
std::int64_t cellAt(const Quadtree& tree, double u, double v, std::uint32_t depth) {
  return tree.contains(u, v) ? static_cast<std::int64_t>(tree.nodeIndexAt(u, v, depth)) : -1;
}

// A leaf's fill: white when empty, darker with log(1 + polygons), kFullGrey from Maxpoly on.
double leafGrey(std::uint32_t polygons, std::uint32_t maxPoly) {
  const double t = std::min(1.0, std::log1p(polygons) / std::log1p(std::max(maxPoly, 1u)));
  return kEmptyGrey - (kEmptyGrey - kFullGrey) * t;
}

// A one-band Byte image encoded as PNG by GDAL's driver (a MEM dataset copied to an in-memory
// file), then written to `to`.
void encodePng(int width, int height, const std::vector<std::uint8_t>& grey, std::ostream& to) {
  ensureGdalRegistered();
  GDALDriver* mem = GetGDALDriverManager()->GetDriverByName("MEM");
  GDALDriver* png = GetGDALDriverManager()->GetDriverByName("PNG");
  if (!mem || !png) throw Error("this GDAL has no PNG driver");
  std::unique_ptr<GDALDataset> ds(mem->Create("", width, height, 1, GDT_Byte, nullptr));
  if (!ds) throw Error("cannot allocate a " + std::to_string(width) + " x " + std::to_string(height) + " image");
  if (ds->GetRasterBand(1)->RasterIO(GF_Write, 0, 0, width, height, const_cast<std::uint8_t*>(grey.data()), width,
                                     height, GDT_Byte, 0, 0) != CE_None) {
    throw Error("cannot fill the image");
  }
  static std::atomic<unsigned> serial{0};
  const std::string name = "/vsimem/qota_render_tree_" + std::to_string(serial++) + ".png";
  CPLPushErrorHandler(CPLQuietErrorHandler);
  CPLErrorReset();
  std::unique_ptr<GDALDataset> copy(
      png->CreateCopy(name.c_str(), ds.get(), FALSE, nullptr, GDALDummyProgress, nullptr));
  const std::string gdalError = CPLGetLastErrorMsg();
  CPLPopErrorHandler();
  const bool ok = copy != nullptr;
  copy.reset();  // flush and close before taking the bytes
  vsi_l_offset length = 0;
  GByte* bytes = ok ? VSIGetMemFileBuffer(name.c_str(), &length, TRUE) : nullptr;
  VSIUnlink(name.c_str());
  VSIUnlink((name + ".aux.xml").c_str());
  if (!bytes) throw Error("cannot encode the PNG" + (gdalError.empty() ? std::string() : " (" + gdalError + ")"));
  to.write(reinterpret_cast<const char*>(bytes), static_cast<std::streamsize>(length));
  CPLFree(bytes);
}

// Fails early, before the work, when the output's folder is missing or not writable (the file
// itself is only created, under a temporary name, once the image is ready).
void requireWritableFolder(const std::string& path) {
  std::filesystem::path folder = std::filesystem::path(path).parent_path();
  if (folder.empty()) folder = ".";
  std::error_code ec;
  if (!std::filesystem::is_directory(folder, ec)) {
    throw Error(path + ": cannot write (no folder " + folder.string() + ")");
  }
  if (::access(folder.c_str(), W_OK) != 0) {
    throw Error(path + ": cannot write (" + std::generic_category().message(errno) + ")");
  }
}

bool hasPngExtension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  return ext == ".png";
}

}  // namespace

int renderTree(const RenderTreeOptions& o, std::ostream& out, std::ostream& err) {
  try {
    if (o.output.empty()) throw Error("an output file is needed: -o OUT.png");
    if (!hasPngExtension(o.output)) throw Error(o.output + ": the picture is a PNG; name it .png");
    if (o.size < kMinSize || o.size > kMaxSize) {
      throw Error("--size must be " + std::to_string(kMinSize) + ".." + std::to_string(kMaxSize) + " pixels, got " +
                  std::to_string(o.size));
    }
    requireWritableFolder(o.output);
    // The tree: from a tree file (qota build) as it is, or built from a DEM. The picture lies on
    // the raster's grid with a hillshade when there is a raster (the DEM, or the one a cartesian
    // tree file was built from, if it is still there); otherwise on the tree's own (u, v) box
    // (longitude and latitude for a planet), u to the right and v up.
    std::optional<TreeFile> treeFile;
    std::optional<DemTerrain> dem;
    std::optional<CartesianIndex> built;
    const Quadtree* treePtr = nullptr;
    // A raster's map coordinates (x, y) to the tree's (u, v): the index's mapping of (x, y, 0).
    std::function<Point2(double, double)> toTree;
    const auto mapsFrom = [&toTree](const auto& index) {
      toTree = [&index](double x, double y) {
        const Eigen::Vector3d m = index.mapping().toMapped(Eigen::Vector3d(x, y, 0));
        return Point2{m.x(), m.y()};
      };
    };
    const SourceOptions& so = o.source;
    std::uint32_t maxPoly = so.index.tree.maxPoly, maxDepth = so.index.tree.maxDepth;
    requireSource(so.source);
    if (isTreeFile(so.source) || !mappingEntry(so.mapping).map || !isRaster(so.source) || so.radius != 0 ||
        so.length != 0 || so.origin || !so.heightRef.empty()) {
      // A tree file, a mesh or a raster in another mapping: opened as sample and build open it.
      treeFile.emplace(openIndex(so));
      std::visit([&](const auto& index) { treePtr = &index.tree(); }, treeFile->index);
      maxPoly = treePtr->options().maxPoly, maxDepth = treePtr->options().maxDepth;
      const TreeSource& from = treeFile->source;
      if (mappingEntry(mappingNameOf(treeFile->index)).map && from.width > 0 && std::filesystem::exists(from.path)) {
        dem.emplace(loadDem(from.path, {.band = from.band, .lonLatAsCartesian = true}));
        std::visit(mapsFrom, treeFile->index);
      }
    } else {
      // Drawn on the raster's own grid: a lon/lat raster's degrees are fine here.
      dem.emplace(loadDem(so.source, {.band = so.band, .lonLatAsCartesian = true, .fillVoids = so.fillVoids}));
      built.emplace(dem->mesh, dem->mapping, so.index);
      treePtr = &built->tree();
      mapsFrom(*built);
    }
    const Quadtree& tree = *treePtr;
    const Box2 box = tree.box();
    const int gridW = dem ? dem->width : 0, gridH = dem ? dem->height : 0;
    // The hillshade in metres (a raster without CRS: its own units, heights in the same unit).
    std::optional<LocalFrame> frame;
    Eigen::Vector3d light = Eigen::Vector3d::UnitZ();
    if (dem) {
      frame.emplace(localFrame(*dem, true, std::hypot(dem->geotransform[1], dem->geotransform[4])));
      light = frame->towardSun(SunPosition{});  // gdaldem's 315, 45
    }

    // The image: the raster's pixel grid (or the tree's box) scaled so that its long side has
    // o.size pixels.
    const double boxW = box.empty() ? 1 : box.uhi - box.ulo, boxH = box.empty() ? 1 : box.vhi - box.vlo;
    const double aspectW = dem ? gridW : boxW, aspectH = dem ? gridH : boxH;
    const double scale = double(o.size) / std::max(aspectW, aspectH);
    const int iw = std::max(1, int(std::lround(aspectW * scale)));
    const int ih = std::max(1, int(std::lround(aspectH * scale)));
    const double colsPer = double(gridW) / iw, rowsPer = double(gridH) / ih;
    // The depth drawn: as asked, else the deepest whose cells are 8 image pixels or more across
    // (a deeper tree over a large raster would draw as a uniform grey of edges).
    const std::uint32_t depth =
        o.depth >= 0 ? static_cast<std::uint32_t>(o.depth)
                     : static_cast<std::uint32_t>(std::max(1.0, std::floor(std::log2(std::max(iw, ih) / 8.0))));
    // Fractional raster (col, row) of an image pixel's centre, and the leaf there.
    const auto rasterAt = [&](int i, int j) { return std::array<double, 2>{(i + 0.5) * colsPer, (j + 0.5) * rowsPer}; };
    const auto leafRow = [&](int j, std::vector<std::int64_t>& ids) {
      for (int i = 0; i < iw; ++i) {
        if (dem) {
          const auto [col, row] = rasterAt(i, j);
          const auto world = dem->pixelCentre(col - 0.5, row - 0.5);
          const Point2 m = toTree(world[0], world[1]);
          ids[i] = cellAt(tree, m.u, m.v, depth);
        } else {
          ids[i] =
              box.empty() ? -1 : cellAt(tree, box.ulo + (i + 0.5) * boxW / iw, box.vhi - (j + 0.5) * boxH / ih, depth);
        }
      }
    };

    std::vector<std::uint8_t> grey(static_cast<std::size_t>(iw) * ih);
    std::vector<std::int64_t> ids(iw), below(iw);
    leafRow(0, ids);
    for (int j = 0; j < ih; ++j) {
      if (j + 1 < ih) leafRow(j + 1, below);
      for (int i = 0; i < iw; ++i) {
        std::uint8_t& px = grey[static_cast<std::size_t>(j) * iw + i];
        // An edge pixel: the leaf changes to the right or below (so each edge is one pixel wide).
        if ((i + 1 < iw && ids[i + 1] != ids[i]) || (j + 1 < ih && below[i] != ids[i])) {
          px = kEdgeGrey;
          continue;
        }
        // (a node split further than the depth drawn: as full as a leaf can be)
        const Quadtree::Node* node = ids[i] < 0 ? nullptr : &tree.nodes()[static_cast<std::size_t>(ids[i])];
        const double fill = !node                             ? kEmptyGrey
                            : node->count == Quadtree::kInner ? kFullGrey
                                                              : leafGrey(Quadtree::leafSize(*node), maxPoly);
        double shade = 1.0;
        if (dem) {
          const auto [col, row] = rasterAt(i, j);
          const int c = std::clamp(int(col), 0, gridW - 1), r = std::clamp(int(row), 0, gridH - 1);
          if (frame->valid[static_cast<std::size_t>(r) * gridW + c]) shade = hillshadeAt(*frame, c, r, light);
        }
        px = static_cast<std::uint8_t>(std::lround(fill * (1 - kShadeDepth + kShadeDepth * shade)));
      }
      std::swap(ids, below);
    }

    AtomicFile file(o.output);
    encodePng(iw, ih, grey, file.stream());
    file.commit();
    if (!o.quiet) {
      const QuadtreeStats t = tree.stats();
      out << "qota render-tree: " << o.source.source << " -> " << o.output << '\n'
          << "tree: " << t.nodes << " nodes, " << t.leaves << " leaves (" << t.emptyLeaves << " empty), depth "
          << t.depth << " (max poly " << maxPoly << ", max depth " << maxDepth << ")\n"
          << "image: " << iw << " x " << ih << " pixels, drawn to depth " << depth
          << (o.depth < 0 ? " (cells of 8 pixels or more; --depth N for another)" : "") << "; white: empty leaf, grey "
          << int(kFullGrey) << ": " << maxPoly << " polygons or more (log scale) or split deeper, grey "
          << int(kEdgeGrey) << ": edges\n"
          << "written: " << o.output << '\n';
    }
    return 0;
  } catch (...) {
    return reportFailure("render-tree", err);
  }
}

}  // namespace qota::tools
