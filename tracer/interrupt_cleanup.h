// Temporary files that an interrupted process removes. A render stopped with
// Ctrl-C (SIGINT), SIGTERM or a closed terminal (SIGHUP) used to leave its hidden ".NAME.PID-N.tmp.png"
// beside the output, since nothing runs destructors when a signal kills a
// process. AtomicOutputFile (output_file.h) registers each temporary here
// while it may exist; a command that installs remove_temporaries_on_interrupt()
// has them unlinked before it dies of the signal.
//
// The handler's reach is kept small, as a signal handler must: it only walks a
// fixed table of paths copied in beforehand, calls unlink(2) on each, restores
// the signal's default action and raises it again, so the process still ends
// "killed by SIGINT" (status 130 in a shell) and a parent sees why. It touches
// no heap, no locks, no stdio. A path that does not fit a slot, or a temporary
// beyond the table's slots, is not registered and stays behind, as before.
#pragma once

#include <string>

namespace rayfarm {

// Installs the handler for SIGINT, SIGTERM and SIGHUP, except where the signal
// is ignored (a background job of a script, `nohup`): that choice is the caller's.
// `render` (in-process or with --workers), the one-job `broker`, `spd -o`,
// `study`, and `fetch` and `submit --wait` before they write frames install it.
void remove_temporaries_on_interrupt();

// That handler, for one that ends the process on `number` (a second stop
// signal, stop_signals.h): unlinks every registered temporary, then raises
// `number` again with its default action, delivered when the handler returns.
// Async-signal-safe; call it only from a handler of `number`.
extern "C" void remove_temporaries_and_reraise(int number);

// Registers `path` for the handler while this object lives, or until forget().
class RemovedOnInterrupt {
 public:
  explicit RemovedOnInterrupt(const std::string& path);
  ~RemovedOnInterrupt() { forget(); }
  RemovedOnInterrupt(const RemovedOnInterrupt&) = delete;
  RemovedOnInterrupt& operator=(const RemovedOnInterrupt&) = delete;

  // The path is no longer a temporary of ours (renamed into place, or removed).
  void forget();

 private:
  int slot_ = -1;  // -1: not registered
};

}  // namespace rayfarm
