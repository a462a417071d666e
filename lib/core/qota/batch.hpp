// What every index's batch queries share: the output's size check, and the split of a batch into
// slices on several threads.
#pragma once

#include <algorithm>
#include <cstddef>
#include <string>
#include <thread>
#include <vector>

#include "qota/error.hpp"

namespace qota::batch {

// Throws qota::Error when a batch's output has no room for every point.
inline void requireRoom(const char* what, std::size_t points, std::size_t room) {
  if (room < points) {
    throw Error(std::string(what) + ": " + std::to_string(points) + " points but room for " + std::to_string(room) +
                " answers");
  }
}

// Runs slice(lo, hi) over [0, n) on `threads` threads (0: one per hardware thread; fewer when a
// thread would get fewer than minPerThread items), the first slice on the calling thread. The
// answers of a batch never depend on how it was sliced.
template <class Slice>
void inSlices(std::size_t n, unsigned threads, std::size_t minPerThread, Slice&& slice) {
  if (threads == 0) threads = std::max(1u, std::thread::hardware_concurrency());
  threads = static_cast<unsigned>(std::min<std::size_t>(threads, n / std::max<std::size_t>(minPerThread, 1) + 1));
  if (threads <= 1) return slice(std::size_t{0}, n);
  std::vector<std::jthread> workers;
  const std::size_t each = (n + threads - 1) / threads;
  for (unsigned k = 1; k < threads; ++k) {
    const std::size_t lo = std::min(n, k * each), hi = std::min(n, lo + each);
    workers.emplace_back([lo, hi, &slice] { slice(lo, hi); });
  }
  slice(std::size_t{0}, std::min(n, each));
}

}  // namespace qota::batch
