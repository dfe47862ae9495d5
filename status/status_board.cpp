// The status page's state; see status_board.h.
#include "status/status_board.h"

#include <algorithm>
#include <cstring>

#include "status/preview.h"

namespace rayfarm {
namespace {

using nlohmann::json;

// rows_per_second averages over this window.
constexpr std::chrono::seconds kRateWindow{10};

}  // namespace

StatusBoard::StatusBoard(size_t keep_images) : keep_images_(std::max<size_t>(1, keep_images)) {}

StatusBoard::Job& StatusBoard::job_entry(const FarmProgress& p) {
  for (Job& j : jobs_)
    if (j.id == p.job) return j;
  Job j;
  j.id = p.job;
  j.scene = p.scene_name;
  j.width = p.width;
  j.height = p.height;
  j.rows_total = p.rows_total;
  j.rgb.assign(static_cast<size_t>(p.width) * p.height * 3, 0.f);
  j.done.assign(static_cast<size_t>(p.height), false);
  jobs_.push_back(std::move(j));
  // Only the newest jobs keep their pixels.
  size_t with_image = 0;
  for (auto it = jobs_.rbegin(); it != jobs_.rend(); ++it)
    if (!it->rgb.empty() && ++with_image > keep_images_) {
      it->rgb = {};
      it->done = {};
    }
  return jobs_.back();
}

void StatusBoard::update(const FarmProgress& p) {
  const auto now = Clock::now();
  std::lock_guard<std::mutex> lock(mutex_);
  workers_ = p.worker_views;
  if (p.job != rejected_job_) {  // the broker counts rejections per job
    for (const auto& [reason, n] : rejected_) rejected_total_[reason] += static_cast<uint64_t>(n);
    rejected_job_ = p.job;
  }
  rejected_ = p.rejected;
  for (double s : p.new_round_trips) round_trip_.observe(s);
  if (p.job != 0 && p.image) {
    Job& j = job_entry(p);
    const size_t row_floats = static_cast<size_t>(j.width) * 3;
    for (const auto& [y0, y1] : p.new_bands) {
      if (!j.rgb.empty())
        std::memcpy(&j.rgb[row_floats * y0], &(*p.image)[row_floats * y0], row_floats * (y1 - y0) * sizeof(float));
      for (int y = y0; y < y1; ++y)
        if (!j.done.empty()) j.done[static_cast<size_t>(y)] = true;
      rows_done_total_ += static_cast<uint64_t>(y1 - y0);
    }
    j.rows_done = p.rows_done;
  }
  rate_samples_.emplace_back(now, rows_done_total_);
  while (rate_samples_.size() > 2 && now - rate_samples_[1].first > kRateWindow) rate_samples_.pop_front();
}

void StatusBoard::set_record(uint64_t job, const json& record) {
  std::lock_guard<std::mutex> lock(mutex_);
  for (Job& j : jobs_)
    if (j.id == job) j.record = record;
}

const StatusBoard::Job* StatusBoard::find(uint64_t job) const {
  for (const Job& j : jobs_)
    if (j.id == job) return &j;
  return nullptr;
}

json StatusBoard::summary(const Job& j) const {
  // Job ids are 44-bit; JSON numbers are exact up to 2^53, so JavaScript reads them whole.
  return {{"id", j.id},
          {"scene", j.scene},
          {"state", j.finished() ? "done" : "running"},
          {"rows_done", j.rows_done},
          {"rows_total", j.rows_total},
          {"width", j.width},
          {"height", j.height}};
}

json StatusBoard::jobs_json() const {
  std::lock_guard<std::mutex> lock(mutex_);
  json out = json::array();
  for (const Job& j : jobs_) out.push_back(summary(j));
  return out;
}

std::optional<json> StatusBoard::job_json(uint64_t job) const {
  std::lock_guard<std::mutex> lock(mutex_);
  const Job* j = find(job);
  if (!j) return std::nullopt;
  return summary(*j);
}

std::optional<json> StatusBoard::record(uint64_t job) const {
  std::lock_guard<std::mutex> lock(mutex_);
  const Job* j = find(job);
  if (!j || j->record.is_null()) return std::nullopt;
  return j->record;
}

json StatusBoard::workers_json() const {
  std::lock_guard<std::mutex> lock(mutex_);
  json out = json::array();
  for (const WorkerView& w : workers_)
    out.push_back({{"name", w.name},
                   {"serial", w.serial},
                   {"weight", w.weight},
                   {"task_rows", w.task_rows},
                   {"rows_per_s", w.busy_s > 0 ? w.rows / w.busy_s : 0.0},
                   {"rows_done", w.rows},
                   {"tasks_done", w.tasks},
                   {"tasks_in_flight", w.in_flight},
                   {"busy_s", w.busy_s},
                   {"last_heard_s", w.last_heard_s},
                   {"state", w.state}});
  return out;
}

std::optional<std::string> StatusBoard::preview_png(uint64_t job) const {
  int width = 0, height = 0;
  std::vector<float> rgb;
  std::vector<bool> done;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    const Job* j = find(job);
    if (!j || j->rgb.empty()) return std::nullopt;
    width = j->width;
    height = j->height;
    rgb = j->rgb;  // encoded outside the lock: the broker thread must not wait on zlib
    done = j->done;
  }
  return rayfarm::preview_png(width, height, rgb, done);
}

FarmMetrics StatusBoard::metrics() const {
  std::lock_guard<std::mutex> lock(mutex_);
  FarmMetrics m;
  m.rows_done = rows_done_total_;
  if (rate_samples_.size() >= 2) {
    const double dt = std::chrono::duration<double>(rate_samples_.back().first - rate_samples_.front().first).count();
    if (dt > 0) m.rows_per_second = static_cast<double>(rate_samples_.back().second - rate_samples_.front().second) / dt;
  }
  for (const char* state : {"loading", "rendering", "idle", "lost", "left"}) m.workers_by_state[state] = 0;
  for (const WorkerView& w : workers_) m.workers_by_state[w.state] += 1;
  m.rejected_by_reason = rejected_total_;
  for (const auto& [reason, n] : rejected_) m.rejected_by_reason[reason] += static_cast<uint64_t>(n);
  m.task_round_trip = round_trip_;
  return m;
}

std::map<std::string, int> StatusBoard::jobs_by_state() const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::map<std::string, int> out{{"running", 0}, {"done", 0}};
  for (const Job& j : jobs_) out[j.finished() ? "done" : "running"] += 1;
  return out;
}

}  // namespace rayfarm
