// Temporaries removed on SIGINT, SIGTERM and SIGHUP; see interrupt_cleanup.h.
#include "tracer/interrupt_cleanup.h"

#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cstring>

#include "tracer/stop_signals.h"

namespace rayfarm {
namespace {

// A process has a few temporaries at a time (an image, a stats file).
constexpr int kSlots = 16;
constexpr size_t kMaxPathBytes = 4096;  // PATH_MAX, with its final NUL

// A slot's path is written only between free and ready, and read by the
// handler only after it has claimed the slot (ready -> removing), so it never
// sees a path half-written or reused. A slot left removing is never freed:
// the process is about to end.
enum SlotState : int { kFree, kFilling, kReady, kRemoving };

struct Slot {
  std::atomic<int> state{kFree};
  char path[kMaxPathBytes];
};
static_assert(std::atomic<int>::is_always_lock_free, "the handler may only use lock-free atomics");

Slot g_slots[kSlots];

void install(int number) {
  if (ignored_from_start(number)) return;
  struct sigaction action {};
  action.sa_handler = remove_temporaries_and_reraise;
  sigemptyset(&action.sa_mask);
  for (const int other : kStopSignals) sigaddset(&action.sa_mask, other);  // one handler at a time
  ::sigaction(number, &action, nullptr);
}

}  // namespace

extern "C" void remove_temporaries_and_reraise(int number) {
  for (Slot& slot : g_slots) {
    int ready = kReady;
    if (slot.state.compare_exchange_strong(ready, kRemoving)) ::unlink(slot.path);
  }
  // Blocked while this handler runs, the signal raised again is delivered on
  // return, with its default action: the process ends killed by it.
  ::signal(number, SIG_DFL);
  ::raise(number);
}

void remove_temporaries_on_interrupt() {
  for (const int number : kStopSignals) install(number);
}

RemovedOnInterrupt::RemovedOnInterrupt(const std::string& path) {
  if (path.size() >= kMaxPathBytes) return;
  for (int i = 0; i < kSlots; ++i) {
    int free = kFree;
    if (!g_slots[i].state.compare_exchange_strong(free, kFilling)) continue;
    std::memcpy(g_slots[i].path, path.c_str(), path.size() + 1);
    g_slots[i].state.store(kReady);  // after the path: the handler reads it only once ready
    slot_ = i;
    return;
  }
}

void RemovedOnInterrupt::forget() {
  if (slot_ < 0) return;
  int ready = kReady;
  g_slots[slot_].state.compare_exchange_strong(ready, kFree);  // fails only while the handler removes it
  slot_ = -1;
}

}  // namespace rayfarm
