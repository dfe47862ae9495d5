// Scanline task pool; see task_board.h.
#include "broker/task_board.h"

#include <algorithm>
#include <cassert>
#include <cstring>
#include <set>

namespace rayfarm {

const char* verdict_name(Verdict v) {
  switch (v) {
    case Verdict::accepted: return "accepted";
    case Verdict::duplicate: return "duplicate";
    case Verdict::beaten: return "beaten";
    case Verdict::stale: return "stale";
    case Verdict::unassigned: return "unassigned";
    case Verdict::mismatch: return "mismatch";
  }
  return "?";
}

TaskBoard::TaskBoard(int height, int width, const std::vector<std::pair<int, int>>& restored)
    : height_(height), width_(width), fresh_(height), pixels_done_(static_cast<size_t>(height), 0) {
  assert(width >= 1);
  for (const auto& [y0, y1] : restored) {
    assert(0 <= y0 && y0 < y1 && y1 <= height);
    rows_restored_ += fresh_.exclude(y0, y1);
    std::fill(pixels_done_.begin() + y0, pixels_done_.begin() + y1, width);
  }
  rows_done_ = rows_restored_;
}

int TaskBoard::rows_waiting() const {
  // In whole rows: a row being cut into spans waits until its last span is
  // handed out, and a row with a requeued span waits until that span is
  // handed out again (once, however many of its spans were lost).
  int rows = rows_fresh() + static_cast<int>(open_.size());
  std::set<int> span_rows;
  for (uint32_t id : requeued_) {
    const TaskRecord& t = tasks_[id];
    if (t.done || t.live > 0) continue;
    if (!t.span) {
      rows += t.rows();
    } else if (!open_.count(t.y0)) {
      span_rows.insert(t.y0);
    }
  }
  return rows + static_cast<int>(span_rows.size());
}

TaskRecord& TaskBoard::issue(TaskRecord& t, uint32_t worker, const std::string& worker_name, double now, bool backup) {
  assert(worker != 0);
  TaskAttempt a;
  a.attempt = t.attempt() + 1;
  a.worker = worker;
  a.worker_name = worker_name;
  a.dispatched = now;
  a.backup = backup;
  t.attempts.push_back(std::move(a));
  t.live += 1;
  return t;
}

const TaskRecord* TaskBoard::reissue(uint32_t worker, const std::string& worker_name, double now) {
  while (!requeued_.empty()) {
    TaskRecord& t = tasks_[requeued_.front()];
    requeued_.pop_front();
    if (!t.done && t.live == 0) return &issue(t, worker, worker_name, now, false);
  }
  return nullptr;
}

const TaskRecord* TaskBoard::next(uint32_t worker, const std::string& worker_name, int rows, double now) {
  assert(rows >= 1);
  if (const TaskRecord* t = reissue(worker, worker_name, now)) return t;
  const auto band = fresh_.take(rows);
  return band ? add_task(worker, worker_name, PixelBand{band->first, band->second, 0, width_}, now) : nullptr;
}

const TaskRecord* TaskBoard::cut(uint32_t worker, const std::string& worker_name, int y0, int y1, double now) {
  assert(0 <= y0 && y0 < y1 && y1 <= height_);
  const int taken = fresh_.exclude(y0, y1);
  assert(taken == y1 - y0);  // every row fresh
  (void)taken;
  return add_task(worker, worker_name, PixelBand{y0, y1, 0, width_}, now);
}

const TaskRecord* TaskBoard::cut_span(uint32_t worker, const std::string& worker_name, int y, int x0, int x1,
                                      double now) {
  assert(0 <= y && y < height_ && 0 <= x0 && x0 < x1 && x1 <= width_);
  auto it = open_.find(y);
  if (it == open_.end()) {
    assert(x0 == 0 && fresh_.is_free(y));
    fresh_.exclude(y, y + 1);
    if (x1 < width_) open_.emplace(y, x1);
  } else {
    assert(x0 == it->second);
    if (x1 < width_) it->second = x1;
    else open_.erase(it);
  }
  return add_task(worker, worker_name, PixelBand{y, y + 1, x0, x1}, now);
}

std::optional<std::pair<int, int>> TaskBoard::open_span() const {
  if (open_.empty()) return std::nullopt;
  return *open_.begin();
}

const TaskRecord* TaskBoard::add_task(uint32_t worker, const std::string& worker_name, const PixelBand& band,
                                      double now) {
  TaskRecord t;
  t.id = static_cast<uint32_t>(tasks_.size());
  t.y0 = band.y0;
  t.y1 = band.y1;
  t.x0 = band.x0;
  t.x1 = band.x1;
  t.span = band.x0 > 0 || band.x1 < width_;
  tasks_.push_back(std::move(t));
  return &issue(tasks_.back(), worker, worker_name, now, false);
}

const TaskRecord& TaskBoard::backup(uint32_t task, uint32_t worker, const std::string& worker_name, double now) {
  TaskRecord& t = tasks_.at(task);
  assert(!t.done && t.live > 0);
  return issue(t, worker, worker_name, now, true);
}

TaskAttempt* TaskBoard::live_attempt(TaskRecord& t, uint32_t worker) {
  for (TaskAttempt& a : t.attempts)
    if (a.worker == worker && std::strcmp(a.outcome, "in_flight") == 0) return &a;
  return nullptr;
}

// The checks run from "task is finished" to "rows differ" so each dropped
// result is counted under the most telling reason.
Verdict TaskBoard::judge(uint32_t worker, uint32_t task, uint32_t attempt, const PixelBand& band) const {
  if (task >= tasks_.size()) return Verdict::unassigned;
  const TaskRecord& t = tasks_[task];
  if (t.done) {
    const bool own_loser = attempt >= 1 && attempt <= t.attempt() && t.attempts[attempt - 1].worker == worker &&
                           std::strcmp(t.attempts[attempt - 1].outcome, "beaten") == 0;
    return own_loser ? Verdict::beaten : Verdict::duplicate;
  }
  if (attempt == 0 || attempt > t.attempt()) return Verdict::unassigned;
  const TaskAttempt& a = t.attempts[attempt - 1];
  if (std::strcmp(a.outcome, "in_flight") != 0) return Verdict::stale;  // a lost attempt
  if (a.worker != worker) return Verdict::unassigned;
  if (!(band == t.band())) return Verdict::mismatch;
  return Verdict::accepted;
}

bool TaskBoard::holds(uint32_t worker, uint32_t task, uint32_t attempt) const {
  if (task >= tasks_.size()) return false;
  const TaskRecord& t = tasks_[task];
  if (t.done || attempt == 0 || attempt > t.attempt()) return false;
  const TaskAttempt& a = t.attempts[attempt - 1];
  return a.worker == worker && std::strcmp(a.outcome, "in_flight") == 0;
}

Verdict TaskBoard::accept(uint32_t worker, uint32_t task, uint32_t attempt, const PixelBand& band, double now,
                          double render_s, double throttle_s) {
  const Verdict v = judge(worker, task, attempt, band);
  if (v != Verdict::accepted) return v;
  TaskRecord& t = tasks_[task];
  TaskAttempt& a = t.attempts[attempt - 1];
  t.done = true;
  t.live = 0;
  t.winner = static_cast<int>(attempt - 1);
  t.finished = now;
  t.render_s = render_s;
  t.throttle_s = throttle_s;
  t.started = std::max(a.dispatched, now - render_s - throttle_s);
  for (TaskAttempt& other : t.attempts)
    if (std::strcmp(other.outcome, "in_flight") == 0) other.outcome = "beaten";
  a.finished = now;
  a.outcome = "done";
  for (int y = t.y0; y < t.y1; ++y) {
    int& done = pixels_done_[static_cast<size_t>(y)];
    done += t.x1 - t.x0;
    assert(done <= width_);
    rows_done_ += done == width_;
  }
  return Verdict::accepted;
}

void TaskBoard::requeue(uint32_t task, uint32_t worker, double now) {
  TaskRecord& t = tasks_.at(task);
  TaskAttempt* a = t.done ? nullptr : live_attempt(t, worker);
  if (!a) return;
  a->finished = now;
  a->outcome = "lost";
  if (--t.live == 0) requeued_.push_back(task);
}

}  // namespace rayfarm
