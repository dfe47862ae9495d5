// TaskBoard: the scanline task pool of one job. Tasks are cut from the rows not
// yet handed out, coarse to fine (broker/row_order.h), at the size of the
// worker that asks (so a fast machine gets more rows per task). A lost task
// keeps its rows and id and is re-issued first with attempt + 1; a result is
// accepted only from the worker holding the task's current attempt, and only
// once (protocol/SPEC.md, rule 4).
// A job resumed after a broker restart starts with rows already done: they are
// never cut into tasks.
#pragma once

#include <cstdint>
#include <deque>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "broker/row_order.h"

namespace rayfarm {

// One hand-out of a task to a worker.
struct TaskAttempt {
  uint32_t attempt = 1;
  uint32_t worker = 0;  // registration serial
  std::string worker_name;
  double dispatched = 0;  // seconds since job start, broker clock
  double finished = -1;
  const char* outcome = "in_flight";  // "in_flight", "done" or "lost"
};

struct TaskRecord {
  uint32_t id = 0;
  int y0 = 0, y1 = 0;
  bool done = false;
  uint32_t holder = 0;  // serial of the worker holding the current attempt, 0 = nobody
  std::vector<TaskAttempt> attempts;  // attempts.back() is the current one
  // Filled when done (broker clock): started = finished - worker busy time.
  double started = -1, finished = -1, render_s = 0, throttle_s = 0;

  uint32_t attempt() const { return attempts.empty() ? 0 : attempts.back().attempt; }
  int rows() const { return y1 - y0; }
};

enum class Verdict { accepted, duplicate, stale, unassigned, mismatch };
const char* verdict_name(Verdict v);

class TaskBoard {
 public:
  // `done`: rows finished before this board existed, as [y0, y1) bands.
  explicit TaskBoard(int height, const std::vector<std::pair<int, int>>& done = {});

  // The next task for `worker`: a requeued one if any, else up to `rows` fresh
  // rows in coarse-to-fine order (fewer where they meet rows handed out
  // already). nullptr when everything is handed out.
  const TaskRecord* next(uint32_t worker, const std::string& worker_name, int rows, double now);

  // Judges a result without changing anything.
  Verdict judge(uint32_t worker, uint32_t task, uint32_t attempt, int y0, int y1) const;
  // Judges a result; on `accepted` marks the task done.
  Verdict accept(uint32_t worker, uint32_t task, uint32_t attempt, int y0, int y1, double now,
                 double render_s, double throttle_s);

  // The worker holding `task` is gone: its rows go back to the front of the queue.
  void requeue(uint32_t task, double now);

  bool complete() const { return rows_done_ == height_; }
  // Rows neither done nor in flight: what is left to hand out.
  int rows_waiting() const;
  int rows_done() const { return rows_done_; }
  int rows_restored() const { return rows_restored_; }
  int height() const { return height_; }
  const std::vector<TaskRecord>& tasks() const { return tasks_; }

 private:
  int height_;
  RowCursor fresh_;  // rows never handed out (restored rows count as handed out)
  int rows_done_ = 0;
  int rows_restored_ = 0;
  std::vector<TaskRecord> tasks_;
  std::deque<uint32_t> requeued_;
};

}  // namespace rayfarm
