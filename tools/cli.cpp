// The qota command's parser: one subcommand per tool (as git, or GDAL's gdal command). Parsing
// only; each tool is a library function in qota_tools.hpp.
#include <CLI/CLI.hpp>
#include <iostream>
#include <map>
#include <new>
#include <string>
#include <vector>

#include "qota/mapping_registry.hpp"
#include "qota_tools.hpp"
#include "text_output.hpp"

namespace qota::tools {
namespace {

void addTreeOptions(CLI::App* app, qota::IndexOptions& terrain) {
  app->add_option("--max-poly", terrain.tree.maxPoly, "Maxpoly: split a quadtree node holding more polygons than this")
      ->capture_default_str()
      ->check(CLI::Range(1u, 1u << 20));
  app->add_option("--max-depth", terrain.tree.maxDepth, "Maxdepth: deepest quadtree level")
      ->capture_default_str()
      ->check(CLI::Range(0u, 30u));
}

// What every tool that reads a source takes, with one meaning (qota::SourceOptions): the band,
// the mapping (choices and help from the registry) and its parameters, the quadtree's.
void addSourceOptions(CLI::App* app, qota::SourceOptions& source) {
  app->add_option("-b,--band", source.band, "Raster band holding the heights (needed when the raster has several)")
      ->check(CLI::Range(1, 1 << 30));
  app->add_option("--mapping", source.mapping,
                  "Frame: " + qota::mappingHelp() + "; default: a tree file's own, else cartesian")
      ->check(CLI::IsMember(qota::mappingNameList()));
  app->add_option("--radius", source.radius,
                  "spherical: the planet's reference radius in metres (default: from the raster's CRS); "
                  "cylindrical: the station's radius (default 250)")
      ->check(CLI::PositiveNumber);
  app->add_option("--length", source.length, "cylindrical: the station's length (default 1000)")
      ->check(CLI::PositiveNumber);
  app->add_option_function<std::vector<double>>(
         "--origin",
         [&source](const std::vector<double>& v) {
           source.origin = std::array<double, 3>{v[0], v[1], v.size() > 2 ? v[2] : 0.0};
         },
         "enu: the frame's origin LAT,LON[,H] (H metres over the ellipsoid); default: the raster's centre at "
         "height 0")
      ->delimiter(',')
      ->expected(2, 3);
  app->add_option("--height-ref", source.heightRef,
                  "geodetic, enu: what the raster's heights are over: ellipsoid, egm96, egm2008, crs (its vertical "
                  "CRS), radius:R (a sphere of radius R metres) or a geoid grid's path; default: its vertical CRS, "
                  "else EGM96 on the Earth and the ellipsoid elsewhere (said once)");
  app->add_flag_function(
      "--fill-voids", [&source](std::int64_t) { source.fillVoids = qota::kFillVoidsPixels; },
      "A raster's voids filled first by GDAL's fill-nodata (gdal_fillnodata: from the void's rim, up to 100 "
      "pixels out); the raster is then read whole");
  addTreeOptions(app, source.index);
}

// GDAL's tools spell some options with one dash and several letters (-az, -alt, -of, -co);
// CLI11 reads a single dash as short flags, so those spellings become --az, --alt, --of, --co
// (and gdalinfo's -stats, -json: --stats, --json).
// gdallocationinfo's point options mean what they mean there: -l_srs is --srs, -wgs84 is
// --srs EPSG:4326 (longitude, latitude), -geoloc (the raster's own georeferencing) is the default.
std::vector<std::string> gdalStyleArguments(int argc, const char* const* argv) {
  std::vector<std::string> args;
  for (int i = 0; i < argc; ++i) {
    const std::string a = argv[i];
    if (i > 0 &&
        (a == "-az" || a == "-alt" || a == "-of" || a == "-co" || a == "-oo" || a == "-stats" || a == "-json")) {
      args.push_back("-" + a);
    } else if (i > 0 && a == "-l_srs") {
      args.push_back("--srs");
    } else if (i > 0 && a == "-wgs84") {
      args.push_back("--srs"), args.push_back("EPSG:4326");
    } else if (i == 0 || a != "-geoloc") {
      args.push_back(a);
    }
  }
  return args;
}

// What qota shadow and qota viewshed read alike (RasterJobOptions): the DEM and the raster out,
// and how the DEM is placed in its frame.
void addRasterJobOptions(CLI::App* cmd, RasterJobOptions& o, const std::string& preview) {
  cmd->add_option("source", o.source, "Elevation raster (any GDAL format)")->required();
  cmd->add_option("-o,--output", o.output, "Output raster")->required();
  cmd->add_option("--of", o.format, "GDAL format (-of); default: from the extension");
  cmd->add_option("--co", o.creationOptions, "Creation option NAME=VALUE (-co), repeatable");
  cmd->add_flag("-q,--quiet", o.quiet, "No progress or summary");
  cmd->add_flag("--flat", o.flat,
                "No curvature: a geographic DEM's lon/lat scaled linearly, a projected DEM's grid as it is");
  cmd->add_option("--mapping", o.mapping,
                  "Frame: geodetic (a DEM with a CRS on its ellipsoid, the default) or cartesian (as --flat)")
      ->check(CLI::IsMember(qota::mappingNameList()));
  cmd->add_option("-b,--band", o.band, "Raster band holding the heights")->check(CLI::Range(1, 1 << 30));
  cmd->add_option("-z,--z-factor", o.zFactor,
                  "Multiply heights by this after converting their unit to metres (gdaldem's -z)")
      ->check(CLI::PositiveNumber);
  cmd->add_option("-s,--scale", o.scale,
                  "Horizontal units per vertical unit, for a raster whose vertical unit is not "
                  "known (gdaldem's -s; a degree counts as 111120 m)")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--pixel-size", o.pixelSize, "Metres per pixel for a raster without CRS");
  cmd->add_option("--height-ref", o.heightRef,
                  "On the ellipsoid: what the heights are over: ellipsoid, egm96, egm2008, crs or a "
                  "geoid grid's path; default: the raster's vertical CRS, else EGM96 on the Earth and "
                  "the ellipsoid elsewhere (said in the frame line, recorded in the output)");
  cmd->add_option("--png", o.png, "Also write a PNG preview: " + preview + " over a hillshade");
  cmd->add_flag("--fill-voids", o.fillVoids,
                "The DEM's voids filled first by GDAL's fill-nodata (gdal_fillnodata: from the void's rim, up to "
                "100 pixels out), so that they get values too (recorded in the output); the whole raster in "
                "memory");
}

int parseAndRun(int argc, const char* const* argv, std::istream& in, std::ostream& out, std::ostream& err) {
  CLI::App app{"qota: terrain following with the Quick Oriented Terrain Algorithm (MERL TR-96-17, 1996)"};
  app.require_subcommand(1);
  app.set_version_flag("--version", versionText, "Print qota's version and its libraries' and exit");

  SampleOptions sample;
  CLI::App* sampleCmd =
      app.add_subcommand("sample",
                         "Terrain height under points. Reads 'x y [fields...]' lines (or 'x y z [fields...]' with "
                         "--query-z: the nearest terrain at or below z) from stdin or --input-file and prints one "
                         "line per input line: the height in the raster's own vertical unit (as gdallocationinfo "
                         "prints it; a mesh's z), 'none' where there is no terrain, 'error' for a malformed line, "
                         "followed by the line's other fields unchanged. Between the outermost pixel centres and "
                         "the raster's edge, the height of the nearest point on the outermost centres' lines. Exit "
                         "code 1 when a line was malformed or off the raster, 2 when the source cannot be read.");
  sampleCmd
      ->add_option("source", sample.source, "Elevation raster (any GDAL format), tree file (qota build) or mesh file")
      ->required();
  sampleCmd->add_option("-i,--input-file", sample.inputFile, "Read points from this file");
  sampleCmd->add_option(
      "-o,--output,--output-file", sample.outputFile,
      "Write results to this file (replaced only when complete; a device such as /dev/null is written in place)");
  sampleCmd->add_flag("-q,--quiet", sample.quiet, "No notes on stderr (a point's problem is still reported)");
  sampleCmd->add_option("--srs", sample.srs,
                        "CRS of the input points (EPSG:4326, WKT, PROJ...; gdallocationinfo's -l_srs; -wgs84: "
                        "EPSG:4326 as longitude latitude); default: the raster's (-geoloc)");
  sampleCmd
      ->add_option("-p,--precision", sample.precision,
                   "Decimals to print (0 to 100); default: the shortest that round-trips")
      ->check(CLI::Range(0, kMaxPrecision));
  sampleCmd->add_flag("--query-z", sample.queryZ,
                      "The third field of a line is the query height: answer the nearest terrain "
                      "at or below it (else it is passed through like any other field)");
  sampleCmd->add_flag("--header", sample.header, "The first line is a header: print 'height' and its other names");
  sampleCmd->add_flag("--world", sample.printWorld, "Also print the world point x y z of the hit");
  sampleCmd->add_flag("-w,--lat-lon", sample.swapXY, "Input lines are 'lat lon' (or 'y x') instead of 'lon lat'");
  sampleCmd
      ->add_option("--output-height-ref", sample.outputHeightRef,
                   "geodetic: print heights over the ellipsoid (ellipsoid) instead of the source's own "
                   "reference")
      ->check(CLI::IsMember({"ellipsoid"}));
  sampleCmd
      ->add_option("-r,--resampling", sample.resampling,
                   "How a raster's height at a point is found: triangle (the exact surface of the raster's "
                   "triangles, as every qota tool sees it), or GDAL's rules: nearest (the pixel containing the "
                   "point, as gdallocationinfo prints), bilinear, cubic (on pixel centres, GDAL's kernels and "
                   "nodata rules)")
      ->capture_default_str()
      ->check(CLI::IsMember({"triangle", "nearest", "bilinear", "cubic"}));
  sampleCmd
      ->add_option("--field", sample.field,
                   "A vector layer of points: the name of the height field added to the output layer")
      ->capture_default_str();
  sampleCmd->add_option("--of", sample.outputFormat,
                        "A vector layer of points: the OGR driver of the output layer (-of); default: by extension");
  sampleCmd->add_option("--layer", sample.layer, "A vector layer of points: the input layer (default: the first)");
  sampleCmd->add_option("--oo", sample.openOptions,
                        "A vector layer of points: an open option NAME=VALUE of the input (-oo; a CSV's "
                        "X_POSSIBLE_NAMES=..., Y_POSSIBLE_NAMES=...), repeatable");
  addSourceOptions(sampleCmd, sample);

  InfoOptions info;
  CLI::App* infoCmd =
      app.add_subcommand("info",
                         "What a source is: a raster's driver, bands, CRS, heights, extent, ground pixel size and the "
                         "memory each tool would take, without building anything; --tree adds the quadtree "
                         "statistics (the paper's Table 4). A tree file or mesh is read and its tree described.");
  infoCmd
      ->add_option("source", info.source.source,
                   "Elevation raster (any GDAL format), tree file (qota build) or mesh file")
      ->required();
  infoCmd->add_flag("-q,--quiet", info.quiet, "No notes (info prints none today)");
  infoCmd->add_flag("--tree", info.tree,
                    "Build the quadtree and print its statistics (implied by --max-poly and --max-depth)");
  infoCmd->add_flag("--stats", info.stats, "Read every pixel: each band's height range and void pixels (-stats)");
  infoCmd->add_flag("--json", info.json, "One JSON object, keys the labels in snake case (-json)");
  addSourceOptions(infoCmd, info.source);

  ShadowOptions shadow;
  CLI::App* shadowCmd =
      app.add_subcommand("shadow",
                         "Shadows of the sun (or any directional light) on a DEM. "
                         "Output: a raster on the DEM's grid, lit = 255, shadow = 0, nodata = 128 (Byte), or hours of "
                         "direct sunlight (Float32, nodata -1) with --hours. Terrain outside the raster is not seen: "
                         "shadows cast from beyond the edge are missing, up to the 'shadow reach' the tool prints "
                         "(relief / tan(altitude)); pad tiles by that much. A DEM with a CRS is placed on its "
                         "ellipsoid (curvature included, the sun's direction right at every pixel) unless --flat. "
                         "Heights are converted to metres from the raster's vertical unit (-z and -s as gdaldem's).");
  addRasterJobOptions(shadowCmd, shadow, "the shadows");
  shadowCmd->add_option("--az", shadow.azimuth, "Sun azimuth (-az), degrees clockwise from north (default 315)");
  shadowCmd->add_option("--alt", shadow.altitude, "Sun altitude (-alt), degrees above the horizon (default 45)");
  std::vector<double> sunVector;
  shadowCmd->add_option("--sun-vector", sunVector, "Vector toward the light: east,north,up")
      ->delimiter(',')
      ->expected(3);
  std::vector<double> at, sunVectorBody, subsolar, lightPoint;
  shadowCmd
      ->add_option("--light-point", lightPoint,
                   "X,Y,Z: a point light (a lamp, a floodlight) at X,Y in the raster's CRS, Z metres above the "
                   "surface there (--light-point-absolute: over the DEM's height reference); the same mask kinds")
      ->delimiter(',')
      ->expected(3);
  shadowCmd->add_flag("--light-point-absolute", shadow.lightPointAbsolute,
                      "--light-point's Z is a height over the DEM's reference (metres), not above the surface");
  shadowCmd->add_option("--at", at, "LON,LAT: -az/-alt are east-north-up at this place (default: the DEM's centre)")
      ->delimiter(',')
      ->expected(2);
  shadowCmd
      ->add_option("--sun-vector-body", sunVectorBody,
                   "X,Y,Z: the direction to the Sun in the body-fixed, body-centred frame (ECEF; "
                   "SPICE's spkpos in IAU_MARS, IAU_MOON): the same light at any place, poles included")
      ->delimiter(',')
      ->expected(3);
  shadowCmd
      ->add_option("--subsolar", subsolar,
                   "LON,LAT: the Sun over this point (east longitude, planetocentric latitude: the "
                   "Sun's declination)")
      ->delimiter(',')
      ->expected(2);
  shadowCmd->add_option("--time", shadow.time,
                        "Date and time, ISO 8601 with its UTC offset (2024-06-21T14:00+02:00, or "
                        "...Z), or without one and --tz: the Sun's position seen from the DEM's "
                        "centre (Earth: VSOP87; Mars: Mars24)");
  shadowCmd->add_option("--tz", shadow.tz,
                        "Zone of a --time without offset: an offset (+02:00) or an IANA name "
                        "(Europe/Paris)");
  std::vector<double> hours;
  shadowCmd
      ->add_option("--hours", hours,
                   "START END STEP: hours of direct sunlight between these local clock hours "
                   "(0 to 48) of --time's date, in steps of STEP hours (at least 1/60); a "
                   "pixel lit at a step's middle counts the whole step")
      ->expected(3);
  shadowCmd->add_option("--lit-value", shadow.litValue, "Output value of lit pixels")->capture_default_str();
  shadowCmd->add_option("--shadow-value", shadow.shadowValue, "Output value of shadowed pixels")->capture_default_str();
  shadowCmd->add_option("--nodata-value", shadow.nodataValue, "Output value (and nodata) of pixels without data")
      ->capture_default_str();
  std::string maxMemory;
  shadowCmd->add_option("--max-memory", maxMemory,
                        "Memory the run may take (64M, 2G...); a raster whose whole shadow would not fit "
                        "is shadowed by tiles with halos (the same values), streamed into a tiled GeoTIFF "
                        "or COG. Default: three quarters of the memory available");
  shadowCmd
      ->add_option("--max-pixels,--max-cells", shadow.maxPixels,
                   "Refuse a raster of more pixels than this (with the time it would take), before "
                   "any work: raise it to run one that large (--max-cells: its older name)")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  shadowCmd
      ->add_option("--tile-size", shadow.tileSize,
                   "Shadow by tiles of N x N pixels (a multiple of 16), whatever the raster's size")
      ->check(CLI::Range(16, 1 << 20));
  std::vector<int> tileAt;
  shadowCmd
      ->add_option("--tile", tileAt,
                   "Compute only tile COL,ROW (from 0) of the --tile-size grid, with its halo, as a "
                   "raster of its own (for batch schedulers; qota assemble joins the tiles)")
      ->delimiter(',')
      ->expected(2);
  shadowCmd->add_option("--tiles-state", shadow.tilesState,
                        "By tiles: read the pass over the heights (height range, frame) from FILE when it "
                        "exists, else make it and write it there: the jobs of a batch (--tile) make it once");
  addTreeOptions(shadowCmd, shadow.index);
  shadowCmd
      ->add_option("--search", shadow.search,
                   "How each pixel's light ray finds the terrain it may meet (the same mask): 'strips' "
                   "(default; strips of the DEM along the sun's azimuth, sorted by distance) or "
                   "'quadtree' (the paper's shadow quadtree in the light's frame)")
      ->transform(
          CLI::CheckedTransformer(std::map<std::string, qota::ShadowSearch>{{"strips", qota::ShadowSearch::Strips},
                                                                            {"quadtree", qota::ShadowSearch::Quadtree}},
                                  CLI::ignore_case));

  ViewshedOptions viewshedOptions;
  CLI::App* viewshedCmd = app.add_subcommand(
      "viewshed",
      "Which pixels an observer sees, exactly, on the triangulated terrain: a pixel is visible when the "
      "straight segment from the observer to its centre (plus --target-height) meets no terrain between its "
      "ends (voids do not block). On the DEM's ellipsoid by default (curvature exact: straight lines in "
      "geocentric coordinates), or --flat. Output: Byte on the DEM's grid, visible 255, not visible 0, "
      "nodata 128, beyond --max-distance 64.");
  addRasterJobOptions(viewshedCmd, viewshedOptions, "the viewshed");
  std::vector<double> observer;
  viewshedCmd->add_option("--observer,--ox", observer, "X,Y: the observer, in the raster's CRS (or --srs)")
      ->delimiter(',')
      ->expected(2);
  viewshedCmd->add_option("--observers", viewshedOptions.observersFile,
                          "Cumulative: how many of these observers see each pixel (UInt16). Any OGR point layer "
                          "(GeoPackage, GeoJSON, Shapefile, CSV with x/y or lon/lat columns) in its own CRS (a CSV "
                          "in --srs), or text lines 'x y [height]' in the raster's CRS (or --srs)");
  viewshedCmd->add_option("--which", viewshedOptions.whichFile,
                          "With --observers: also a raster of which observers see each pixel, bit k for the k-th "
                          "(Byte up to 7 observers, UInt16 up to 15, UInt32 up to 31; the metadata names each bit)");
  viewshedCmd
      ->add_option("--height-field", viewshedOptions.heightField,
                   "The --observers layer's field holding each observer's height (metres above the surface; "
                   "missing or null: --observer-height)")
      ->capture_default_str();
  viewshedCmd->add_option("--srs", viewshedOptions.srs, "CRS of --observer (EPSG:4326, WKT, PROJ; x = lon/easting)");
  viewshedCmd
      ->add_option("--observer-height,--oz", viewshedOptions.observerHeight,
                   "Metres above the surface at the observer (0 to 1e9)")
      ->capture_default_str();
  viewshedCmd
      ->add_option("--target-height,--tz", viewshedOptions.targetHeight, "Metres above each pixel's surface (0 to 1e9)")
      ->capture_default_str();
  viewshedCmd
      ->add_option("--max-distance,--md", viewshedOptions.maxDistance,
                   "Metres (horizontal, from the observer); pixels beyond are not tested (0: no limit)")
      ->capture_default_str();
  viewshedCmd
      ->add_option("--refraction", viewshedOptions.refraction,
                   "Refraction coefficient k (0.13 is usual for the Earth): lines of sight bend with curvature k/R, "
                   "modelled as the terrain raised by k d^2 / 2R; on the ellipsoid, one observer (default 0: straight)")
      ->capture_default_str();
  viewshedCmd->add_option("--visible-value,--vv", viewshedOptions.visibleValue, "Output value of visible pixels")
      ->capture_default_str();
  viewshedCmd->add_option("--invisible-value,--iv", viewshedOptions.hiddenValue, "Output value of hidden pixels")
      ->capture_default_str();
  viewshedCmd->add_option("--nodata-value,--dv", viewshedOptions.nodataValue, "Output value (and nodata) of voids")
      ->capture_default_str();
  viewshedCmd
      ->add_option("--out-of-range-value,--ov", viewshedOptions.outOfRangeValue,
                   "Output value of pixels beyond --max-distance")
      ->capture_default_str();
  viewshedCmd->add_flag("--per-pixel", viewshedOptions.perPixel,
                        "Test every pixel's line of sight through the quadtree instead of the exact sweep (flat) or "
                        "the walk over the squares under it (on the ellipsoid): the same answers, slower; for "
                        "comparison");
  addTreeOptions(viewshedCmd, viewshedOptions.index);

  AssembleOptions assembleOptions;
  CLI::App* assembleCmd =
      app.add_subcommand("assemble",
                         "Join tiles (qota shadow --tile runs, or any one-band rasters on one grid) into one raster: "
                         "a GeoTIFF or COG written a tile at a time, or a VRT pointing at them. Refuses tiles on "
                         "other grids, overlapping, or missing from their run (named), rather than leave a hole.");
  assembleCmd->add_option("tiles", assembleOptions.tiles, "The tiles")->required();
  assembleCmd->add_option("-o,--output", assembleOptions.output, "Output raster (.tif, .vrt)")->required();
  assembleCmd->add_option("--of", assembleOptions.format, "GTiff, COG or VRT; default: from the extension");
  assembleCmd->add_option("--co", assembleOptions.creationOptions, "Creation option NAME=VALUE (-co), repeatable");
  assembleCmd->add_flag("-q,--quiet", assembleOptions.quiet, "No progress or summary");

  BuildOptions build;
  CLI::App* buildCmd =
      app.add_subcommand("build",
                         "Build a terrain's QOTA index once and write it as a tree file (.qota), which sample, info "
                         "and render-tree load instead of rebuilding.");
  buildCmd
      ->add_option("source", build.source.source,
                   "Raster (any GDAL format) or mesh file (OBJ, PLY, glTF, STL, GeoPackage...)")
      ->required();
  buildCmd->add_option("-o,--output", build.output, "Tree file to write (replaced only when complete)")->required();
  buildCmd->add_flag("-q,--quiet", build.quiet, "No summary");
  addSourceOptions(buildCmd, build.source);

  RenderTreeOptions renderTree;
  CLI::App* renderTreeCmd =
      app.add_subcommand("render-tree",
                         "A picture of the QOTA quadtree over a DEM (the paper's Figure 4): a grey PNG on the "
                         "raster's grid, each leaf filled by its polygon count (white = empty, darker on a log scale "
                         "down to grey 160 at --max-poly polygons or more), leaf edges in dark grey (40), over a "
                         "faint hillshade.");
  renderTreeCmd
      ->add_option("source", renderTree.source.source,
                   "Elevation raster (any GDAL format), mesh file or tree file (qota build; its "
                   "own Maxpoly and Maxdepth; drawn over its raster when that is still "
                   "there, else over its (u, v) box, as a mesh or a raster in a curved mapping is)")
      ->required();
  renderTreeCmd->add_option("-o,--output", renderTree.output, "Output PNG")->required();
  renderTreeCmd->add_option("--size", renderTree.size, "Pixels along the image's long side")
      ->capture_default_str()
      ->check(CLI::Range(16, 16384));
  renderTreeCmd
      ->add_option("--depth", renderTree.depth,
                   "Draw the tree down to this depth (deeper nodes as their ancestor there); default: the deepest "
                   "whose cells are 8 image pixels or more across")
      ->check(CLI::Range(0, 30));
  renderTreeCmd->add_flag("-q,--quiet", renderTree.quiet, "No summary");
  addSourceOptions(renderTreeCmd, renderTree.source);

  try {
    const std::vector<std::string> args = gdalStyleArguments(argc, argv);
    std::vector<const char*> cargs;
    cargs.reserve(args.size());
    for (const auto& a : args) cargs.push_back(a.c_str());
    app.parse(static_cast<int>(cargs.size()), const_cast<char**>(cargs.data()));
  } catch (const CLI::ParseError& e) {
    // CLI11 prints help (exit 0) or the parse error (non-zero).
    const int code = app.exit(e, out, err);
    return code == 0 ? 0 : 2;
  }
  if (*buildCmd) return tools::build(build, out, err);
  if (*sampleCmd) {
    return tools::sample(sample, in, out, err);
  }
  if (*infoCmd) {
    info.tree = info.tree || infoCmd->count("--max-poly") > 0 || infoCmd->count("--max-depth") > 0;
    return tools::info(info, out, err);
  }
  if (*shadowCmd) {
    if (!sunVector.empty()) shadow.sunVector = Eigen::Vector3d(sunVector[0], sunVector[1], sunVector[2]);
    if (!sunVectorBody.empty())
      shadow.sunVectorBody = Eigen::Vector3d(sunVectorBody[0], sunVectorBody[1], sunVectorBody[2]);
    if (!subsolar.empty()) shadow.subsolar = std::array<double, 2>{subsolar[0], subsolar[1]};
    if (!at.empty()) shadow.at = std::array<double, 2>{at[0], at[1]};
    if (!lightPoint.empty()) shadow.lightPoint = std::array<double, 3>{lightPoint[0], lightPoint[1], lightPoint[2]};
    if (!hours.empty()) shadow.hours = std::array<double, 3>{hours[0], hours[1], hours[2]};
    if (!tileAt.empty()) shadow.tile = std::array<int, 2>{tileAt[0], tileAt[1]};
    if (!maxMemory.empty()) {
      try {
        shadow.maxMemory = parseByteSize(maxMemory);
      } catch (const std::exception& e) {
        err << "qota shadow: --max-memory " << e.what() << '\n';
        return 2;
      }
    }
    return qota::tools::shadow(shadow, out, err);
  }
  if (*viewshedCmd) {
    if (!observer.empty()) viewshedOptions.observer = std::array<double, 2>{observer[0], observer[1]};
    return tools::viewshed(viewshedOptions, out, err);
  }
  if (*assembleCmd) return tools::assemble(assembleOptions, out, err);
  if (*renderTreeCmd) return tools::renderTree(renderTree, out, err);
  return 2;
}

}  // namespace

int runCli(int argc, const char* const* argv, std::istream& in, std::ostream& out, std::ostream& err) {
  // Every failure ends here as a message and exit code 2, whatever threw it (the tools turn their
  // own into messages; this catches what they could not foresee: memory, the standard library,
  // the libraries underneath).
  const auto fail = [&](const std::string& what) {
    err << "qota: " << what << '\n';
    return 2;
  };
  try {
    recordCommandLine(argc, argv);
    return parseAndRun(argc, argv, in, out, err);
  } catch (const std::bad_alloc&) {
    return fail("out of memory");
  } catch (const std::exception& e) {
    return fail(e.what());
  } catch (...) {
    return fail("unexpected error");
  }
}

}  // namespace qota::tools
