// Progress line; see progress.h.
#include "broker/progress.h"

#include <unistd.h>

namespace rayfarm {

ProgressMeter::ProgressMeter(bool enabled, double interval_s, std::FILE* out)
    : enabled_(enabled), tty_(isatty(fileno(out)) != 0), interval_s_(interval_s), out_(out) {}

std::string ProgressMeter::line(int rows_done, int rows_total, int workers, double elapsed_s,
                                int rows_resumed) const {
  const double rate = elapsed_s > 0 ? (rows_done - rows_resumed) / elapsed_s : 0;
  char eta[32] = "?";
  if (rate > 0) std::snprintf(eta, sizeof eta, "%.1fs", (rows_total - rows_done) / rate);
  char buf[160];
  std::snprintf(buf, sizeof buf, "rows %d/%d (%.0f%%), %.1f rows/s, ETA %s, %d worker(s)", rows_done, rows_total,
                rows_total ? 100.0 * rows_done / rows_total : 100.0, rate, eta, workers);
  return buf;
}

void ProgressMeter::update(int rows_done, int rows_total, int workers, double elapsed_s, int rows_resumed) {
  if (!enabled_) return;
  const double period = tty_ ? 0.2 : interval_s_;
  if (elapsed_s - last_print_ < period) return;
  last_print_ = elapsed_s;
  const std::string text = line(rows_done, rows_total, workers, elapsed_s, rows_resumed);
  if (tty_) {
    std::fprintf(out_, "\r\033[K%s", text.c_str());
    drawn_ = true;
  } else {
    std::fprintf(out_, "rayfarm broker: %s\n", text.c_str());
  }
  std::fflush(out_);
}

void ProgressMeter::clear_line() {
  if (drawn_) std::fprintf(out_, "\r\033[K");
  drawn_ = false;
}

void ProgressMeter::finish(int rows_total, double elapsed_s) {
  if (!enabled_) return;
  clear_line();
  std::fprintf(out_, "rayfarm broker: %d rows in %.2fs\n", rows_total, elapsed_s);
  std::fflush(out_);
}

}  // namespace rayfarm
