#include "qota/memory_budget.hpp"

#include <sys/resource.h>
#include <unistd.h>
#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include <algorithm>
#include <atomic>
#include <fstream>
#include <sstream>

#include "qota/error.hpp"

namespace qota::memory {
namespace {

std::atomic<std::uint64_t> gLimit{0};

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

// The first number in a file ("max" and absent files: 0).
std::uint64_t fileNumber(const std::string& file) {
  std::ifstream in(file);
  std::uint64_t n = 0;
  return in >> n ? n : 0;
}

// What the process's memory control group still allows (v2, else v1), in bytes; 0 when there is
// no limit or none is known. In a container MemAvailable is the host's, not the container's.
std::uint64_t cgroupLeft() {
  std::ifstream in("/proc/self/cgroup");
  std::string v2, v1;  // the group's path in each hierarchy
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("0::", 0) == 0) v2 = line.substr(3);
    const auto memory = line.find(":memory:");
    if (memory != std::string::npos) v1 = line.substr(memory + 8);
  }
  const auto left = [](const std::string& limitFile, const std::string& usageFile) -> std::uint64_t {
    const std::uint64_t limit = fileNumber(limitFile), used = fileNumber(usageFile);
    if (limit == 0 || limit >= (1ull << 60)) return 0;  // "max", or v1's "no limit"
    return limit > used ? limit - used : 1;
  };
  // The path as this process sees it, else the mount's root (a namespaced container's own).
  for (const std::string& dir : {"/sys/fs/cgroup" + v2, std::string("/sys/fs/cgroup")}) {
    if (const auto n = left(dir + "/memory.max", dir + "/memory.current")) return n;
  }
  for (const std::string& dir : {"/sys/fs/cgroup/memory" + v1, std::string("/sys/fs/cgroup/memory")}) {
    if (const auto n = left(dir + "/memory.limit_in_bytes", dir + "/memory.usage_in_bytes")) return n;
  }
  return 0;
}

// What the address-space limit (ulimit -v) still allows; 0 when unlimited.
std::uint64_t addressSpaceLeft() {
  rlimit r{};
  if (getrlimit(RLIMIT_AS, &r) != 0 || r.rlim_cur == RLIM_INFINITY) return 0;
  const std::uint64_t used = procKib("/proc/self/status", "VmSize:"), limit = r.rlim_cur;
  return limit > used ? limit - used : 1;
}

}  // namespace

std::uint64_t availableBytes() {
  std::uint64_t m = procKib("/proc/meminfo", "MemAvailable:");
  if (m == 0) {
    const long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGE_SIZE);
    m = pages > 0 && page > 0 ? static_cast<std::uint64_t>(pages) * static_cast<std::uint64_t>(page) : 0;
  }
  std::uint64_t budgetLeft = 0;
  if (const std::uint64_t limit = gLimit.load()) {
    const std::uint64_t resident = procKib("/proc/self/status", "VmRSS:");
    budgetLeft = limit > resident ? limit - resident : 1;
  }
  for (const std::uint64_t limit : {cgroupLeft(), addressSpaceLeft(), budgetLeft}) {
    if (limit != 0) m = m == 0 ? limit : std::min(m, limit);
  }
  return m;
}

void setLimit(std::uint64_t bytes) { gLimit.store(bytes); }

std::uint64_t peakBytes() { return procKib("/proc/self/status", "VmHWM:"); }

std::uint64_t residentBytes() {
  // What the process holds, not what its allocator keeps of what was freed: the budgets are
  // planned from this, after the checks that read and free a geoid grid, the raster's blocks...
  releaseFreedMemory();
  return procKib("/proc/self/status", "VmRSS:");
}

void releaseFreedMemory() {
#if defined(__GLIBC__)
  malloc_trim(0);  // glibc keeps freed memory in each thread's arena unless asked
#endif
}

std::string gib(std::uint64_t bytes) {
  std::ostringstream s;
  s.precision(3);
  s << static_cast<double>(bytes) / (1024.0 * 1024.0 * 1024.0) << " GiB";
  return s.str();
}

void require(const std::string& what, const PerItem& cost, std::uint64_t vertices, std::uint64_t triangles) {
  const std::uint64_t need = cost.bytes(vertices, triangles);
  // Reading what is available costs system calls (/proc, the control group): worth it for the
  // large builds it guards, not for the small indexes built by the thousand (a sampler's tiles).
  constexpr std::uint64_t kAlwaysFits = 16u << 20;
  if (need <= kAlwaysFits) return;
  const std::uint64_t available = availableBytes();
  if (available && need > available) {
    throw Error(what + ": " + std::to_string(vertices) + " vertices and " + std::to_string(triangles) +
                " triangles need about " + gib(need) + " to index, more than the " + gib(available) +
                " of memory available");
  }
}

}  // namespace qota::memory
