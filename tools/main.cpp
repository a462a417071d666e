// The qota command: one executable, one subcommand per tool (as git, or GDAL's gdal command).
// Parsing only; each tool is a library function in qota_tools.hpp.
#include <CLI/CLI.hpp>
#include <iostream>

#include "qota_tools.hpp"

namespace {

void addTreeOptions(CLI::App* app, qota::TerrainOptions& terrain) {
  app->add_option("--max-poly", terrain.tree.maxPoly,
                  "Maxpoly: split a quadtree node holding more polygons than this")
      ->capture_default_str()
      ->check(CLI::Range(1u, 1u << 20));
  app->add_option("--max-depth", terrain.tree.maxDepth, "Maxdepth: deepest quadtree level")
      ->capture_default_str()
      ->check(CLI::Range(0u, 30u));
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "qota: terrain following with the Quick Oriented Terrain Algorithm (MERL TR-96-17, 1996)"};
  app.require_subcommand(1);

  qota::tools::SampleOptions sample;
  CLI::App* sampleCmd = app.add_subcommand(
      "sample",
      "Terrain height under points. Reads 'x y' or 'x y z' lines (z: the nearest terrain at or "
      "below it) from stdin or --input-file and prints one line per input line: the height, "
      "'none' where there is no terrain, 'error' for a malformed line. Exit code 1 when a line "
      "was malformed or off the raster, 2 when the raster cannot be read.");
  sampleCmd->add_option("source", sample.source, "Elevation raster (any GDAL format)")->required();
  sampleCmd->add_option("-i,--input-file", sample.inputFile, "Read points from this file");
  sampleCmd->add_option("-o,--output-file", sample.outputFile,
                        "Write results to this file (replaced only when complete)");
  sampleCmd->add_option("--srs", sample.srs,
                        "CRS of the input points (EPSG:4326, WKT, PROJ...); default: the raster's");
  sampleCmd->add_option("-p,--precision", sample.precision,
                        "Decimals to print; default: the shortest that round-trips");
  sampleCmd->add_flag("--world", sample.printWorld, "Also print the world point x y z of the hit");
  addTreeOptions(sampleCmd, sample.terrain);

  qota::tools::InfoOptions info;
  CLI::App* infoCmd =
      app.add_subcommand("info", "Raster, terrain and quadtree statistics (the paper's Table 4)");
  infoCmd->add_option("source", info.source, "Elevation raster (any GDAL format)")->required();
  addTreeOptions(infoCmd, info.terrain);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // CLI11 prints help (exit 0) or the parse error (non-zero).
    const int code = app.exit(e);
    return code == 0 ? 0 : 2;
  }
  if (*sampleCmd) return qota::tools::sample(sample, std::cin, std::cout, std::cerr);
  if (*infoCmd) return qota::tools::info(info, std::cout, std::cerr);
  return 2;
}
