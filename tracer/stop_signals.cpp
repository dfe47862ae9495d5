// Which stop signals a command may take over; see stop_signals.h.
#include "tracer/stop_signals.h"

#include <signal.h>

namespace rayfarm {

bool ignored_from_start(int number) {
  struct sigaction old {};
  return ::sigaction(number, nullptr, &old) != 0 || old.sa_handler == SIG_IGN;
}

void handle_stop_signals(void (*handler)(int)) {
  for (const int number : kStopSignals)
    if (!ignored_from_start(number)) std::signal(number, handler);
}

}  // namespace rayfarm
