// Stopping on a signal without leaving half-written outputs (see cancel.hpp).
#include "cancel.hpp"

#include <csignal>
#include <cstring>
#include <string>

#include "qota/error.hpp"

namespace qota::tools {
namespace {

volatile std::sig_atomic_t gSignal = 0;

extern "C" void onSignal(int sig) {
  if (gSignal != 0) {  // the second: at once
    std::signal(sig, SIG_DFL);
    std::raise(sig);
    return;
  }
  gSignal = sig;
}

}  // namespace

void installCancelHandlers() {
  for (const int sig : {SIGINT, SIGTERM, SIGHUP}) {
    struct sigaction action {};
    action.sa_handler = onSignal;
    sigemptyset(&action.sa_mask);
    sigaction(sig, &action, nullptr);
  }
}

bool cancelRequested() { return gSignal != 0; }

int cancelSignal() { return gSignal; }

void throwIfCancelled() {
  if (const int sig = gSignal) {
    const char* name = sig == SIGINT ? "SIGINT" : sig == SIGTERM ? "SIGTERM" : sig == SIGHUP ? "SIGHUP" : "a signal";
    throw Error(std::string("cancelled by ") + name + "; nothing was written");
  }
}

}  // namespace qota::tools
