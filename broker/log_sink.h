// LogSink: where the broker and the service send their log lines. Tests and
// embedding programs pass their own; without one, lines go to stderr with the
// prefix every head-node line carries.
#pragma once

#include <cstdio>
#include <functional>
#include <string>

#include "tracer/log_text.h"

namespace rayfarm {

using LogSink = std::function<void(const std::string&)>;

inline void write_log(const LogSink& sink, const std::string& line) {
  const std::string safe = escape_control_characters(line);
  if (sink)
    sink(safe);
  else
    std::fprintf(stderr, "rayfarm broker: %s\n", safe.c_str());
}

}  // namespace rayfarm
