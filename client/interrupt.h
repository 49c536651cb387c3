#pragma once
// Ctrl-C and SIGTERM for `pf`: the signals are blocked in every thread and received by one
// thread with sigwait, so the reaction runs as ordinary code (it may take locks, cancel RPCs and
// signal child processes) instead of inside an async signal handler.
//
// With no handler installed a signal ends the process at once with exit code 130 (what the
// in-process render always did). Farm commands install a handler that cancels the watch and
// stops the local farm; the command then returns 130 after cleaning up.

#include <functional>

namespace pf {

// Call first thing in main(), before any thread exists (children inherit the mask: LocalFarm
// resets it after fork).
void InstallInterruptHandling();

// `handler(n)` runs on the signal thread for the n-th signal (1, 2, ...); it must be quick and
// must not call SetInterruptHandler. Pass {} to restore the default (exit 130). After this
// returns, the previous handler is not running and will not run again.
void SetInterruptHandler(std::function<void(int)> handler);

bool Interrupted();

}  // namespace pf
