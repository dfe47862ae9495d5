// ProgressMeter: the broker's progress line on stderr. On a terminal it redraws
// one line in place a few times a second; otherwise (logs, CI) it prints a plain
// line every `interval_s` so log files stay readable.
#pragma once

#include <cstdio>
#include <string>

namespace rayfarm {

class ProgressMeter {
 public:
  ProgressMeter(bool enabled, double interval_s, std::FILE* out = stderr);

  // rows_done of rows_total after `elapsed_s`; prints when due. `rows_resumed`
  // of rows_done were done before this run began (journaled before a broker
  // restart): they count as done but not in the rate, so the ETA after a
  // resume is not a burst of rows that arrived in no time.
  void update(int rows_done, int rows_total, int workers, double elapsed_s, int rows_resumed = 0);
  // The line update() prints.
  std::string line(int rows_done, int rows_total, int workers, double elapsed_s, int rows_resumed = 0) const;
  // Ends the in-place line (TTY) so the next log line starts clean.
  void finish(int rows_total, double elapsed_s);
  // Clears a half-drawn TTY line before someone else prints.
  void clear_line();

 private:
  bool enabled_;
  bool tty_;
  double interval_s_;
  std::FILE* out_;
  double last_print_ = -1e9;
  bool drawn_ = false;
};

}  // namespace rayfarm
