// Large blocks on transparent huge pages, for the qota command only (linked into its executable,
// not the library: a program using the library keeps its own allocator).
//
// Why: a whole-raster job touches hundreds of megabytes once (the frame's points, the heights,
// the verdicts). In 4 KiB pages that is one page fault per 4 KiB, a quarter of a 2000 x 2000
// viewshed's time on Linux; in 2 MiB pages it is 512 times fewer. Where the kernel's setting is
// "madvise" (Debian's default) only memory that asks gets huge pages, so a block of 4 MiB or more
// asks before it is first touched. The blocks still come from malloc and go back with free, so
// everything else about the heap (mallopt in main.cpp) holds. Sanitizer builds keep their own
// operator new (GCC says so by __SANITIZE_*__, clang by __has_feature).
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define QOTA_SANITIZED 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer) || __has_feature(memory_sanitizer)
#define QOTA_SANITIZED 1
#endif
#endif

#if defined(__linux__) && !defined(QOTA_SANITIZED)

#include <sys/mman.h>

#include <cstdint>
#include <cstdlib>
#include <new>

namespace {

constexpr std::size_t kHugePage = std::size_t{2} << 20;
constexpr std::size_t kLargeBlock = std::size_t{4} << 20;

void* allocate(std::size_t bytes) {
  if (bytes == 0) bytes = 1;
  for (;;) {
    if (void* p = std::malloc(bytes)) {
      if (bytes >= kLargeBlock) {
        // The whole huge pages inside the block (advice only: a failure changes nothing).
        const auto base = reinterpret_cast<std::uintptr_t>(p);
        const std::uintptr_t first = (base + kHugePage - 1) & ~(kHugePage - 1),
                             last = (base + bytes) & ~(kHugePage - 1);
        if (last > first) madvise(static_cast<char*>(p) + (first - base), last - first, MADV_HUGEPAGE);
      }
      return p;
    }
    const std::new_handler handler = std::get_new_handler();
    if (!handler) throw std::bad_alloc();
    handler();
  }
}

}  // namespace

void* operator new(std::size_t bytes) { return allocate(bytes); }
void* operator new[](std::size_t bytes) { return allocate(bytes); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }

#endif
