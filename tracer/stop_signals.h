// The signals that end a command: Ctrl-C (SIGINT), kill's default (SIGTERM)
// and a closed terminal or ssh session (SIGHUP). Every command that acts on
// them -- a worker and the service stop cleanly, a render removes its
// temporaries -- follows one rule: a signal the process started with ignored
// (a background job of a script starts with SIGINT ignored, `nohup` with
// SIGHUP) stays ignored, since the caller chose that.
#pragma once

#include <csignal>

namespace rayfarm {

inline constexpr int kStopSignals[] = {SIGINT, SIGTERM, SIGHUP};

// Whether `number` is ignored now, as the process started (asked before any
// handler of ours is installed).
bool ignored_from_start(int number);

// Installs `handler` for each of kStopSignals not ignored_from_start().
void handle_stop_signals(void (*handler)(int));

}  // namespace rayfarm
