// Scanline task pool; see task_board.h.
#include "broker/task_board.h"

#include <algorithm>
#include <cassert>

namespace rayfarm {

const char* verdict_name(Verdict v) {
  switch (v) {
    case Verdict::accepted: return "accepted";
    case Verdict::duplicate: return "duplicate";
    case Verdict::stale: return "stale";
    case Verdict::unassigned: return "unassigned";
    case Verdict::mismatch: return "mismatch";
  }
  return "?";
}

TaskBoard::TaskBoard(int height, const std::vector<std::pair<int, int>>& done) : height_(height), fresh_(height) {
  for (const auto& [y0, y1] : done) {
    assert(0 <= y0 && y0 < y1 && y1 <= height);
    rows_restored_ += fresh_.exclude(y0, y1);
  }
  rows_done_ = rows_restored_;
}

// Requeued tasks first (they hold rows an image cannot finish without), then
// fresh rows, coarse to fine, cut to the asking worker's size.
const TaskRecord* TaskBoard::next(uint32_t worker, const std::string& worker_name, int rows, double now) {
  assert(worker != 0 && rows >= 1);
  TaskRecord* task = nullptr;
  while (!requeued_.empty() && !task) {
    TaskRecord& t = tasks_[requeued_.front()];
    requeued_.pop_front();
    if (!t.done && t.holder == 0) task = &t;
  }
  if (!task) {
    const auto band = fresh_.take(rows);
    if (!band) return nullptr;
    TaskRecord t;
    t.id = static_cast<uint32_t>(tasks_.size());
    t.y0 = band->first;
    t.y1 = band->second;
    tasks_.push_back(t);
    task = &tasks_.back();
  }
  TaskAttempt a;
  a.attempt = task->attempt() + 1;
  a.worker = worker;
  a.worker_name = worker_name;
  a.dispatched = now;
  task->attempts.push_back(a);
  task->holder = worker;
  return task;
}

int TaskBoard::rows_waiting() const {
  int rows = 0;
  for (uint32_t id : requeued_)
    if (!tasks_[id].done && tasks_[id].holder == 0) rows += tasks_[id].rows();
  return rows + fresh_.remaining();
}

// The checks run from "task is finished" to "rows differ" so each dropped
// result is counted under the most telling reason.
Verdict TaskBoard::judge(uint32_t worker, uint32_t task, uint32_t attempt, int y0, int y1) const {
  if (task >= tasks_.size()) return Verdict::unassigned;
  const TaskRecord& t = tasks_[task];
  if (t.done) return Verdict::duplicate;
  if (attempt < t.attempt()) return Verdict::stale;
  if (attempt > t.attempt() || t.holder != worker) return Verdict::unassigned;
  if (y0 != t.y0 || y1 != t.y1) return Verdict::mismatch;
  return Verdict::accepted;
}

Verdict TaskBoard::accept(uint32_t worker, uint32_t task, uint32_t attempt, int y0, int y1, double now,
                          double render_s, double throttle_s) {
  const Verdict v = judge(worker, task, attempt, y0, y1);
  if (v != Verdict::accepted) return v;
  TaskRecord& t = tasks_[task];
  t.done = true;
  t.holder = 0;
  t.finished = now;
  t.render_s = render_s;
  t.throttle_s = throttle_s;
  t.started = std::max(t.attempts.back().dispatched, now - render_s - throttle_s);
  t.attempts.back().finished = now;
  t.attempts.back().outcome = "done";
  rows_done_ += t.rows();
  return Verdict::accepted;
}

void TaskBoard::requeue(uint32_t task, double now) {
  TaskRecord& t = tasks_.at(task);
  if (t.done || t.holder == 0) return;
  t.holder = 0;
  t.attempts.back().finished = now;
  t.attempts.back().outcome = "lost";
  requeued_.push_back(task);
}

}  // namespace rayfarm
