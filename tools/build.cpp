// qota build: a terrain's index, built once and written as a tree file (see qota_tools.hpp).
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <iostream>

#include "index_source.hpp"
#include "qota/atomic_file.hpp"
#include "qota/error.hpp"
#include "qota/memory_budget.hpp"
#include "qota_tools.hpp"
#include "text_output.hpp"

namespace qota::tools {

int build(const BuildOptions& options, std::ostream& out, std::ostream& err) {
  try {
    if (options.output.empty()) throw Error("no output file (-o)");
    // Before the build, which can take minutes: a folder that is not there or not writable.
    OutputStage::checkTarget(options.output);
    const std::filesystem::path target(options.output);
    const std::filesystem::path folder = target.has_parent_path() ? target.parent_path() : ".";
    if (!std::filesystem::is_directory(folder)) {
      throw Error(options.output + ": cannot write (no folder " + folder.string() + "); nothing was built");
    }
    if (access(folder.c_str(), W_OK) != 0) {
      throw Error(options.output + ": cannot write (the folder " + folder.string() +
                  " is not writable); nothing was built");
    }
    const auto t0 = std::chrono::steady_clock::now();
    const TreeFile tree = openIndex(options.source);
    const std::uint64_t triangles = std::visit([](const auto& index) { return index.stats().triangles; }, tree.index);
    if (triangles == 0) {
      throw Error(options.source.source +
                  ": no terrain to index (every pixel is nodata, or no polygon has an "
                  "area seen along the mapping's lines); nothing was written");
    }
    const auto t1 = std::chrono::steady_clock::now();
    saveTree(options.output, tree.index, tree.source);
    const auto t2 = std::chrono::steady_clock::now();
    if (!options.quiet) {
      const auto secs = [](auto a, auto b) { return std::chrono::duration<double>(b - a).count(); };
      std::visit(
          [&](const auto& index) {
            out << options.output << ": " << mappingNameOf(tree.index) << " tree of " << index.stats().triangles
                << " triangles, " << index.stats().tree.nodes << " nodes, "
                << std::filesystem::file_size(options.output) << " bytes\n"
                << "built in " << formatNumber(secs(t0, t1), 3) << " s, written in " << formatNumber(secs(t1, t2), 3)
                << " s\n"
                << "memory: peak " << memory::peakBytes() / (1 << 20) << " MiB (estimated "
                << estimatedPeakBytes(tree, options.source) / (1 << 20) << " MiB)\n";
          },
          tree.index);
    }
    return 0;
  } catch (...) {
    return reportFailure("build", err);
  }
}

}  // namespace qota::tools
