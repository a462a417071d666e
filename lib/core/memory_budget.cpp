#include "qota/memory_budget.hpp"

#include <unistd.h>

#include <fstream>
#include <sstream>

#include "qota/error.hpp"

namespace qota::memory {
namespace {

// A "Key:   value kB" line of a /proc file, in bytes; 0 when absent.
std::uint64_t procKib(const char* file, const std::string& wanted) {
  std::ifstream in(file);
  for (std::string line; std::getline(in, line);) {
    if (line.rfind(wanted, 0) != 0) continue;
    std::istringstream fields(line.substr(wanted.size()));
    std::uint64_t kib = 0;
    return fields >> kib ? kib * 1024 : 0;
  }
  return 0;
}

}  // namespace

std::uint64_t availableBytes() {
  if (const std::uint64_t m = procKib("/proc/meminfo", "MemAvailable:")) return m;
  const long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGE_SIZE);
  return pages > 0 && page > 0 ? static_cast<std::uint64_t>(pages) * static_cast<std::uint64_t>(page) : 0;
}

std::uint64_t peakBytes() { return procKib("/proc/self/status", "VmHWM:"); }

std::string gib(std::uint64_t bytes) {
  std::ostringstream s;
  s.precision(3);
  s << static_cast<double>(bytes) / (1024.0 * 1024.0 * 1024.0) << " GiB";
  return s.str();
}

void require(const std::string& what, const PerItem& cost, std::uint64_t vertices, std::uint64_t triangles) {
  const std::uint64_t need = cost.bytes(vertices, triangles), available = availableBytes();
  if (available && need > available) {
    throw Error(what + ": " + std::to_string(vertices) + " vertices and " + std::to_string(triangles) +
                " triangles need about " + gib(need) + " to index, more than the " + gib(available) +
                " of memory available");
  }
}

}  // namespace qota::memory
