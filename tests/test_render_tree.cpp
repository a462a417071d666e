// qota render-tree, called as a library function: the picture's size and grey levels, read back
// with GDAL and compared with the tree the picture shows; errors leave no file.
#include <gdal_priv.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <set>
#include <sstream>
#include <vector>

#include "qota/dem.hpp"
#include "qota/terrain.hpp"
#include "qota_tools.hpp"

namespace {

using qota::tools::RenderTreeOptions;

const std::string kHelens = QOTA_DATA_DIR "/SainteHelens.dem";  // 327 x 468, voids at the edges

std::filesystem::path scratch(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() / "qota_render_tree_tests";
  std::filesystem::create_directories(dir);
  return dir / name;
}

struct Image {
  int width = 0, height = 0, bands = 0;
  std::vector<std::uint8_t> grey;  // band 1, row-major
  int at(int i, int j) const { return grey[static_cast<std::size_t>(j) * width + i]; }
};

Image readPng(const std::filesystem::path& path) {
  qota::ensureGdalRegistered();
  std::unique_ptr<GDALDataset> ds(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
  Image im;
  if (!ds) return im;
  EXPECT_STREQ(ds->GetDriver()->GetDescription(), "PNG");
  im.width = ds->GetRasterXSize(), im.height = ds->GetRasterYSize(), im.bands = ds->GetRasterCount();
  im.grey.resize(static_cast<std::size_t>(im.width) * im.height);
  EXPECT_EQ(ds->GetRasterBand(1)->RasterIO(GF_Read, 0, 0, im.width, im.height, im.grey.data(), im.width, im.height,
                                           GDT_Byte, 0, 0),
            CE_None);
  return im;
}

struct ToolRun {
  int code;
  std::string out, err;
};

ToolRun render(const RenderTreeOptions& o) {
  std::ostringstream out, err;
  const int code = qota::tools::renderTree(o, out, err);
  return {code, out.str(), err.str()};
}

RenderTreeOptions helens(const std::string& name, int size, std::uint32_t maxPoly) {
  RenderTreeOptions o;
  o.source.source = kHelens;
  o.output = scratch(name).string();
  o.size = size;
  o.source.index.tree.maxPoly = maxPoly;
  o.quiet = true;
  std::filesystem::remove(o.output);
  return o;
}

// Pixels darker than any leaf fill (the darkest fill is grey 160 under the deepest hillshade, 0.65,
// so 104): the leaf edges (grey 40).
std::size_t edgePixels(const Image& im) {
  std::size_t n = 0;
  for (std::uint8_t g : im.grey) n += g < 80;
  return n;
}

// Every leaf of the tree with its box in mapped (u, v), by the layout quadtree.hpp documents.
struct Leaf {
  qota::Box2 box;
  std::uint32_t polygons;
};
void collectLeaves(const qota::Quadtree& tree, std::uint32_t node, const qota::Box2& b, int depth,
                   std::vector<Leaf>& leaves) {
  const auto n = tree.nodes()[node];
  if (n.count != qota::Quadtree::kInner) {
    leaves.push_back({b, qota::Quadtree::leafSize(n)});
    return;
  }
  const qota::Box2& root = tree.box();
  const double mu = b.ulo + std::ldexp(root.uhi - root.ulo, -depth - 1);
  const double mv = b.vlo + std::ldexp(root.vhi - root.vlo, -depth - 1);
  const qota::Box2 child[4] = {
      {b.ulo, b.vlo, mu, mv}, {mu, b.vlo, b.uhi, mv}, {b.ulo, mv, mu, b.vhi}, {mu, mv, b.uhi, b.vhi}};
  for (int c = 0; c < 4; ++c) collectLeaves(tree, n.first + c, child[c], depth + 1, leaves);
}

TEST(RenderTree, WritesAPngOfTheRequestedSize) {
  RenderTreeOptions o = helens("size.png", 300, 32);
  o.quiet = false;
  const ToolRun r = render(o);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("leaves"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find(o.output), std::string::npos) << r.out;
  const Image im = readPng(o.output);
  // 468 rows on the long side become 300; 327 columns become 327 * 300 / 468 = 209.6.
  EXPECT_EQ(im.height, 300);
  EXPECT_EQ(im.width, 210);
  EXPECT_EQ(im.bands, 1);
  const std::set<std::uint8_t> levels(im.grey.begin(), im.grey.end());
  EXPECT_GT(levels.size(), 10u);  // fills, hillshade and edges
  EXPECT_GT(edgePixels(im), 0u);

  o.quiet = true;
  o.size = 1000;
  const ToolRun quiet = render(o);
  ASSERT_EQ(quiet.code, 0) << quiet.err;
  EXPECT_EQ(quiet.out, "");
  EXPECT_EQ(readPng(o.output).height, 1000);  // replaced
}

TEST(RenderTree, EmptyLeavesAreWhiteAndFullLeavesGrey) {
  // Maxpoly 32 leaves empty leaves in the voids along the raster's edges; 2048 pixels make the
  // leaves (about 40 x 55 m, 30 m pixels) several pixels wide.
  const RenderTreeOptions o = helens("leaves.png", 2048, 32);
  const ToolRun r = render(o);
  ASSERT_EQ(r.code, 0) << r.err;
  const Image im = readPng(o.output);
  ASSERT_GT(im.width, 0);

  const qota::DemTerrain dem = qota::loadDem(kHelens);
  const qota::CartesianIndex index(dem.mesh, dem.mapping, o.source.index);
  std::vector<Leaf> leaves;
  collectLeaves(index.tree(), 0, index.tree().box(), 0, leaves);
  // The image pixel at a leaf's centre, when the leaf is at least 5 pixels wide and high.
  const auto centrePixel = [&](const Leaf& l, int& i, int& j) {
    const auto pixel = [&](double u, double v) {
      const Eigen::Vector3d w = dem.mapping.toWorld({u, v, 0});
      const auto cr = dem.pixelOf(w.x(), w.y());
      return std::array<double, 2>{cr[0] * im.width / dem.width, cr[1] * im.height / dem.height};
    };
    const auto lo = pixel(l.box.ulo, l.box.vlo), hi = pixel(l.box.uhi, l.box.vhi);
    if (std::abs(hi[0] - lo[0]) < 5 || std::abs(hi[1] - lo[1]) < 5) return false;
    i = static_cast<int>((lo[0] + hi[0]) / 2), j = static_cast<int>((lo[1] + hi[1]) / 2);
    return true;
  };
  int emptyGrey = -1, fullGrey = 256, empties = 0, fulls = 0;
  for (const Leaf& l : leaves) {
    int i = 0, j = 0;
    if (!centrePixel(l, i, j)) continue;
    if (l.polygons == 0) {
      emptyGrey = std::max(emptyGrey, im.at(i, j)), ++empties;
      EXPECT_GT(im.at(i, j), 160) << "empty leaf at pixel " << i << ", " << j;
    } else if (l.polygons >= o.source.index.tree.maxPoly) {
      fullGrey = std::min(fullGrey, im.at(i, j)), ++fulls;
      EXPECT_LE(im.at(i, j), 160) << "full leaf at pixel " << i << ", " << j;
      EXPECT_GE(im.at(i, j), 80) << "full leaf at pixel " << i << ", " << j;
    }
  }
  EXPECT_GT(empties, 0);
  EXPECT_GT(fulls, 100);
  EXPECT_EQ(emptyGrey, 255);  // voids are not shaded
}

TEST(RenderTree, MorePolygonsPerLeafMeansFewerEdges) {
  RenderTreeOptions fine = helens("fine.png", 1000, 32), coarse = helens("coarse.png", 1000, 128);
  fine.depth = coarse.depth = 30;  // (every leaf drawn, however small)
  ASSERT_EQ(render(fine).code, 0);
  ASSERT_EQ(render(coarse).code, 0);
  const Image a = readPng(fine.output), b = readPng(coarse.output);
  ASSERT_EQ(a.grey.size(), b.grey.size());
  // 32824 leaves against 4096: about 3 times the edge length (leaves of about 3 x 4 pixels
  // against 11 x 16).
  EXPECT_GT(edgePixels(a), 2 * edgePixels(b));
  EXPECT_GT(edgePixels(b), 0u);
}

TEST(RenderTree, ErrorsExitTwoAndLeaveNoFile) {
  const auto leftovers = [](const std::filesystem::path& target) {
    int n = 0;
    for (const auto& e : std::filesystem::directory_iterator(target.parent_path())) {
      n += e.path().filename().string().find(target.filename().string()) != std::string::npos;
    }
    return n;
  };
  RenderTreeOptions o = helens("error.png", 300, 256);
  o.output = "/no/such/dir/tree.png";
  ToolRun r = render(o);
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.err.rfind("qota render-tree: /no/such/dir/tree.png: cannot write", 0), 0u) << r.err;
  EXPECT_FALSE(std::filesystem::exists(o.output));

  o = helens("error.png", 300, 256);
  o.source.source = "/no/such/dem.tif";
  r = render(o);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("/no/such/dem.tif"), std::string::npos) << r.err;
  EXPECT_EQ(leftovers(o.output), 0);

  o = helens("error.png", 3, 256);
  r = render(o);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--size"), std::string::npos) << r.err;
  EXPECT_EQ(leftovers(o.output), 0);

  o = helens("error.tif", 300, 256);
  r = render(o);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("name it .png"), std::string::npos) << r.err;
  EXPECT_EQ(leftovers(o.output), 0);
}

}  // namespace

TEST(RenderTreeTool, DrawsToADepthWhoseCellsCanBeSeen) {
  // The Rainier tile's tree at Maxpoly 8 goes 11 levels deep; at 256 pixels the picture stops
  // where cells are 8 pixels across (depth 5), and --depth draws another.
  qota::tools::RenderTreeOptions o;
  o.source.source = QOTA_DATA_DIR "/mt_rainier_90m.tif";
  o.output = scratch("render_depth.png").string();
  o.size = 256;
  std::ostringstream out, err;
  ASSERT_EQ(qota::tools::renderTree(o, out, err), 0) << err.str();
  EXPECT_NE(out.str().find("drawn to depth 5 (cells of 8 pixels or more"), std::string::npos) << out.str();
  o.depth = 3;
  std::ostringstream out3;
  ASSERT_EQ(qota::tools::renderTree(o, out3, err), 0) << err.str();
  EXPECT_NE(out3.str().find("drawn to depth 3;"), std::string::npos) << out3.str();
}
