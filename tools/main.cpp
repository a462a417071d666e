// The qota command: one executable, one subcommand per tool (tools/cli.cpp parses, each tool is a
// library function in qota_tools.hpp).
#include <csignal>
#include <iostream>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include "cancel.hpp"
#include "qota_tools.hpp"

int main(int argc, char** argv) {
#if defined(__GLIBC__)
  // The tools allocate and free blocks of a few megabytes over and over (a tile's index, a batch
  // of lines): kept in the heap instead of mapped and unmapped each time, they are not faulted in
  // page by page again (a fifth of qota sample's time on a million points). Blocks over 64 MB
  // (a shadow tile's window) are still mapped on their own and returned when freed.
  mallopt(M_MMAP_THRESHOLD, 64 << 20);
  mallopt(M_TRIM_THRESHOLD, 128 << 20);
#endif
  qota::tools::installCancelHandlers();
  const int code = qota::tools::runCli(argc, argv, std::cin, std::cout, std::cerr);
  if (const int sig = qota::tools::cancelSignal()) {  // the outputs are cleaned up: end by the signal
    std::cout.flush();
    std::signal(sig, SIG_DFL);
    std::raise(sig);
  }
  return code;
}
