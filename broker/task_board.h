// TaskBoard: the scanline task pool of one job. A task is a band of rows that
// were not yet handed out: cut at the asking worker's size in coarse-to-fine
// order (next; broker/row_order.h), or at rows a dispatch policy chose (cut),
// or a span of pixels [x0, x1) of one row (cut_span): a dispatch policy cuts
// the last rows of a job into spans, left to right, so that no single row on
// a slow machine sets the end. A row cut into spans is done when all its
// pixels are.
// A lost attempt is requeued with its rows and id and re-issued first with
// attempt + 1; a straggling task may get a backup attempt on another worker
// while the first still runs. A result is accepted from any worker holding a
// live attempt, and only the first one counts (protocol/SPEC.md, rule 4): the
// others become "beaten". A job resumed after a broker restart starts with rows
// already done: they count as handed out and done, and are never cut into tasks.
#pragma once

#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "broker/row_order.h"

namespace rayfarm {

// Rows [y0, y1) and, of each, pixels [x0, x1): what a task covers and what a
// result says it holds.
struct PixelBand {
  int y0 = 0, y1 = 0, x0 = 0, x1 = 0;
  bool operator==(const PixelBand& o) const { return y0 == o.y0 && y1 == o.y1 && x0 == o.x0 && x1 == o.x1; }
};

// One hand-out of a task to a worker.
struct TaskAttempt {
  uint32_t attempt = 1;
  uint32_t worker = 0;  // registration serial
  std::string worker_name;
  double dispatched = 0;  // seconds since job start, broker clock
  double finished = -1;
  bool backup = false;    // issued while another attempt was still live
  const char* outcome = "in_flight";  // "in_flight", "done", "lost" or "beaten"
};

struct TaskRecord {
  uint32_t id = 0;
  int y0 = 0, y1 = 0;
  int x0 = 0, x1 = 0;  // pixels of each row: [0, width) unless a span
  bool span = false;   // one row, part of its pixels (cut_span)
  bool done = false;
  int live = 0;          // attempts in flight
  int winner = -1;       // index into attempts of the accepted one
  std::vector<TaskAttempt> attempts;  // attempts.back() is the newest
  // Filled when done (broker clock): started = finished - worker busy time.
  double started = -1, finished = -1, render_s = 0, throttle_s = 0;

  uint32_t attempt() const { return attempts.empty() ? 0 : attempts.back().attempt; }
  int rows() const { return y1 - y0; }
  int pixels() const { return (y1 - y0) * (x1 - x0); }
  PixelBand band() const { return {y0, y1, x0, x1}; }
  // The attempt that finished the task, else the newest.
  const TaskAttempt& final_attempt() const { return attempts[winner >= 0 ? static_cast<size_t>(winner) : attempts.size() - 1]; }
};

// `beaten`: the task is done, and this was the worker's own attempt that
// another attempt beat (a backup race's loser); `duplicate`: any other result
// for a done task.
enum class Verdict { accepted, duplicate, beaten, stale, unassigned, mismatch };
const char* verdict_name(Verdict v);

class TaskBoard {
 public:
  // `width`: pixels per row (1 = rows cannot be cut into spans). `restored`:
  // rows finished before this board existed, as [y0, y1) bands.
  explicit TaskBoard(int height, int width = 1, const std::vector<std::pair<int, int>>& restored = {});

  // A requeued task if any (the image cannot finish without its rows), else
  // nullptr. `next` and `cut` call it first.
  const TaskRecord* reissue(uint32_t worker, const std::string& worker_name, double now);

  // The next task for `worker`: a requeued one if any, else up to `rows` fresh
  // rows in coarse-to-fine order (fewer where they meet rows handed out
  // already). nullptr when all are handed out.
  const TaskRecord* next(uint32_t worker, const std::string& worker_name, int rows, double now);

  // A new task of rows [y0, y1), which must all be fresh (see is_fresh).
  const TaskRecord* cut(uint32_t worker, const std::string& worker_name, int y0, int y1, double now);

  // A new task of pixels [x0, x1) of row y. Spans of a row are cut left to
  // right: x0 is 0 for a fresh row (which it takes), else open_span()'s x.
  const TaskRecord* cut_span(uint32_t worker, const std::string& worker_name, int y, int x0, int x1, double now);
  // A row cut into spans whose last pixels are not handed out yet: (y, first
  // free x). nullopt when there is none.
  std::optional<std::pair<int, int>> open_span() const;

  // Another attempt of a task that is in flight elsewhere (a backup copy).
  const TaskRecord& backup(uint32_t task, uint32_t worker, const std::string& worker_name, double now);

  // Judges a result without changing anything.
  // `band`: the rows and pixels the result says it holds.
  Verdict judge(uint32_t worker, uint32_t task, uint32_t attempt, const PixelBand& band) const;
  // Whether `attempt` of `task` is live at `worker` (a result it sends for it
  // would be judged on its rows and pixels).
  bool holds(uint32_t worker, uint32_t task, uint32_t attempt) const;
  // Judges a result; on `accepted` marks the task done and its other live attempts beaten.
  Verdict accept(uint32_t worker, uint32_t task, uint32_t attempt, const PixelBand& band, double now,
                 double render_s, double throttle_s);

  // `worker`'s attempt of `task` is lost (the worker is gone, or sent the wrong
  // rows). When no other attempt is live, the rows go back to the front of the queue.
  void requeue(uint32_t task, uint32_t worker, double now);

  bool complete() const { return rows_done_ == height_; }
  bool is_fresh(int y) const { return fresh_.is_free(y); }
  // Whole rows done (a row cut into spans counts once all its spans are).
  int rows_done() const { return rows_done_; }
  int rows_fresh() const { return fresh_.remaining(); }
  // Pixels of row y done: width once the row is done, between 0 and width
  // while its spans come in.
  int pixels_done(int y) const { return pixels_done_[static_cast<size_t>(y)]; }
  // Every pixel is handed out (or done): no fresh row, no open span row.
  bool all_handed_out() const { return rows_fresh() == 0 && open_.empty(); }
  int width() const { return width_; }
  bool has_requeued() const { return !requeued_.empty(); }
  // Rows neither done nor in flight: what is left to hand out.
  int rows_waiting() const;
  int rows_restored() const { return rows_restored_; }
  int height() const { return height_; }
  const std::vector<TaskRecord>& tasks() const { return tasks_; }
  const TaskRecord& task(uint32_t id) const { return tasks_.at(id); }

 private:
  const TaskRecord* add_task(uint32_t worker, const std::string& worker_name, const PixelBand& band, double now);
  TaskRecord& issue(TaskRecord& t, uint32_t worker, const std::string& worker_name, double now, bool backup);
  TaskAttempt* live_attempt(TaskRecord& t, uint32_t worker);

  int height_, width_;
  RowCursor fresh_;  // rows never handed out (restored rows count as handed out)
  int rows_done_ = 0, rows_restored_ = 0;
  std::map<int, int> open_;            // row cut into spans -> first x not handed out
  std::vector<int> pixels_done_;       // per row: pixels done (width once the row is)
  std::vector<TaskRecord> tasks_;
  std::deque<uint32_t> requeued_;
};

}  // namespace rayfarm
