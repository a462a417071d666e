// Ctrl-C, SIGTERM and SIGHUP while a tool runs: the first asks the work to stop at its next
// check (a progress step, a tile, a batch of lines), so that the outputs staged so far are
// removed as the stack unwinds and nothing half-written is left; main then ends by the same
// signal. A second signal ends the process at once (the next run writing into that folder
// removes the staging folder it leaves). Internal to the tool.
#pragma once

namespace qota::tools {

void installCancelHandlers();
// Whether a signal asked the work to stop.
bool cancelRequested();
// Throws qota::Error ("cancelled by SIGTERM") when one did.
void throwIfCancelled();
// The signal that asked (0: none).
int cancelSignal();

}  // namespace qota::tools
