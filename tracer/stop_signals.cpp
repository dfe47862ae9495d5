// Which stop signals a command may take over, and the second one that ends it
// at once; see stop_signals.h.
#include "tracer/stop_signals.h"

#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cstring>

#include "tracer/interrupt_cleanup.h"

namespace rayfarm {
namespace {

static_assert(std::atomic<bool>::is_always_lock_free && std::atomic<void (*)(int)>::is_always_lock_free,
              "the handler may only use lock-free atomics");

std::atomic<void (*)(int)> g_clean_stop{nullptr};  // the command's handler, for the first signal
std::atomic<bool> g_stopping{false};               // a first stop signal came

// One write(2) of the whole line, so that it is not interleaved with another
// thread's log line; no stdio, no heap.
void say_stopping_now(int number) {
  char line[64] = "rayfarm: second ";
  std::strncat(line, stop_signal_name(number), sizeof line - std::strlen(line) - 1);
  std::strncat(line, ": stopping now\n", sizeof line - std::strlen(line) - 1);
  const ssize_t ignored = ::write(STDERR_FILENO, line, std::strlen(line));
  (void)ignored;  // nothing to do about a closed stderr: the process ends anyway
}

extern "C" void on_first_or_second_stop(int number) {
  if (!g_stopping.exchange(true)) {
    if (void (*clean_stop)(int) = g_clean_stop.load()) clean_stop(number);
    return;
  }
  say_stopping_now(number);
  remove_temporaries_and_reraise(number);
}

}  // namespace

bool ignored_from_start(int number) {
  struct sigaction old {};
  return ::sigaction(number, nullptr, &old) != 0 || old.sa_handler == SIG_IGN;
}

void handle_stop_signals(void (*handler)(int)) {
  g_clean_stop = handler;
  for (const int number : kStopSignals) {
    if (ignored_from_start(number)) continue;
    struct sigaction action {};
    action.sa_handler = on_first_or_second_stop;
    action.sa_flags = SA_RESTART;  // as std::signal had it: a read or write under way is not cut short
    sigemptyset(&action.sa_mask);
    for (const int other : kStopSignals) sigaddset(&action.sa_mask, other);  // one at a time: one line, one end
    ::sigaction(number, &action, nullptr);
  }
}

const char* stop_signal_name(int number) {
  return number == SIGINT ? "SIGINT" : number == SIGTERM ? "SIGTERM" : number == SIGHUP ? "SIGHUP" : "a signal";
}

}  // namespace rayfarm
