// The signals that end a command: Ctrl-C (SIGINT), kill's default (SIGTERM)
// and a closed terminal or ssh session (SIGHUP). Every command that acts on
// them -- a worker and the service stop cleanly, a render removes its
// temporaries -- follows one rule: a signal the process started with ignored
// (a background job of a script starts with SIGINT ignored, `nohup` with
// SIGHUP) stays ignored, since the caller chose that.
//
// A clean stop can take long: a worker finishes building the BVH of a large
// scene before it exits, the service waits for a request still arriving. A
// second stop signal meanwhile ends the process at once, as Ctrl-C pressed
// twice does most Unix tools: one line on stderr ("rayfarm: second SIGINT:
// stopping now"), the temporaries of interrupt_cleanup.h removed, and the
// process dies of that signal (status 128+N in a shell). Nothing else runs:
// what the clean stop would have written is left as a kill -9 leaves it, and
// the service's state folder is built to survive that (service/journal.h).
#pragma once

#include <csignal>

namespace rayfarm {

inline constexpr int kStopSignals[] = {SIGINT, SIGTERM, SIGHUP};

// Whether `number` is ignored now, as the process started (asked before any
// handler of ours is installed).
bool ignored_from_start(int number);

// For each of kStopSignals not ignored_from_start(): the first of them calls
// `handler` (which asks the command to stop cleanly; it must be
// async-signal-safe, e.g. set an atomic flag), a second one ends the process
// at once, as above.
void handle_stop_signals(void (*handler)(int));

// "SIGINT", "SIGTERM", "SIGHUP", or "a signal"; async-signal-safe.
const char* stop_signal_name(int number);

}  // namespace rayfarm
