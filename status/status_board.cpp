// The status page's live state; see status_board.h.
#include "status/status_board.h"

#include <algorithm>
#include <cctype>
#include <cstring>

#include "status/preview.h"
#include "tracer/log_text.h"

namespace rayfarm {
namespace {

using nlohmann::json;

// rows_per_second averages over this window.
constexpr std::chrono::seconds kRateWindow{10};

}  // namespace

std::string worker_connect_address(const std::string& endpoint) {
  for (const char* any : {"tcp://0.0.0.0:", "tcp://[::]:", "tcp://*:"})
    if (endpoint.rfind(any, 0) == 0) return "tcp://HEAD:" + endpoint.substr(std::strlen(any));
  return endpoint;
}

std::string broker_public_key_beside(const std::string& broker_key_file) {
  const std::string ext = ".key";
  const size_t stem = broker_key_file.size() - std::min(broker_key_file.size(), ext.size());
  if (broker_key_file.size() <= ext.size() || broker_key_file.compare(stem, ext.size(), ext) != 0) return "BROKER.pub";
  return broker_key_file.substr(0, stem) + ".pub";
}

namespace {

// `word` as one shell word: as it is when nothing in it is special to a shell,
// else single-quoted (a path with a space split the pasted command). A word
// that the log text escapes (a byte that is not UTF-8, a control character)
// is given as $'...' with those escapes, \xe9 where a Latin-1 folder has its
// byte: bash, zsh and ksh read it back as the very bytes, where U+FFFD in
// their place named another file, and the page shows it as the logs do.
std::string shell_word(const std::string& word) {
  const bool plain = !word.empty() && std::all_of(word.begin(), word.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || std::strchr("/._-+:,@%=", c) != nullptr;
  });
  if (plain) return word;
  if (const std::string escaped = escape_control_characters(word); escaped != word) {
    std::string quoted = "$'";
    for (const char c : escaped) quoted += c == '\'' ? std::string("\\'") : std::string(1, c);
    return quoted + "'";
  }
  std::string quoted = "'";
  for (const char c : word) quoted += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return quoted + "'";
}

}  // namespace

std::string worker_command(const std::string& connect, const std::string& broker_public_key) {
  std::string command = "rayfarm worker --connect " + shell_word(connect);
  if (!broker_public_key.empty()) command += " --key WORKER.key --broker-key " + shell_word(broker_public_key);
  return command;
}

StatusBoard::StatusBoard(size_t keep_images) : keep_images_(std::max<size_t>(1, keep_images)) {}

// The job's entry, started afresh when the broker moved on to another frame.
StatusBoard::Job& StatusBoard::job_entry(uint64_t id, const FarmProgress& p) {
  auto it = std::find_if(jobs_.begin(), jobs_.end(), [id](const Job& j) { return j.id == id; });
  if (it == jobs_.end()) {
    jobs_.push_back(Job{});
    jobs_.back().id = id;
    if (jobs_.size() > keep_images_) jobs_.pop_front();
    it = std::prev(jobs_.end());
  }
  Job& j = *it;
  if (j.broker_job != p.job) {
    // Allocated first: a frame too large for memory throws with the entry as it was.
    std::vector<float> rgb(static_cast<size_t>(p.width) * p.height * 3, 0.f);
    std::vector<bool> done(static_cast<size_t>(p.height), false);
    j.rgb = std::move(rgb);
    j.done = std::move(done);
    j.broker_job = p.job;
    j.width = p.width;
    j.height = p.height;
    j.rows_done = p.rows_restored;  // rows accepted in this run count from here
  }
  return j;
}

void StatusBoard::update(const FarmProgress& p, uint64_t job) {
  const auto now = Clock::now();
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<WorkerView> previous = std::move(workers_);
  workers_ = p.worker_views;
  if (p.job == 0)  // between jobs: the table and the load chart keep the last job's work
    for (WorkerView& w : workers_)
      for (const WorkerView& before : previous)
        if (before.serial == w.serial) {
          w.tasks = before.tasks;
          w.rows = before.rows;
          w.busy_s = before.busy_s;
        }
  // The broker restarts its counts when a job starts (and keeps them after it ends).
  if (p.job != 0 && p.job != rejected_job_) {
    rejected_seen_.clear();
    rejected_job_ = p.job;
  }
  for (const auto& [reason, n] : p.rejected) {
    const int before = rejected_seen_[reason];
    rejected_total_[reason] += static_cast<uint64_t>(n >= before ? n - before : n);
  }
  rejected_seen_ = p.rejected;
  for (double s : p.new_round_trips) round_trip_.observe(s);
  if (p.job != 0 && p.image) {
    Job& j = job_entry(job ? job : p.job, p);
    const size_t row_floats = static_cast<size_t>(j.width) * 3;
    for (const auto& [y0, y1] : p.new_bands) {
      std::memcpy(&j.rgb[row_floats * y0], &(*p.image)[row_floats * y0], row_floats * (y1 - y0) * sizeof(float));
      std::fill(j.done.begin() + y0, j.done.begin() + y1, true);
    }
    rows_done_total_ += static_cast<uint64_t>(std::max(0, p.rows_done - j.rows_done));
    j.rows_done = p.rows_done;
  }
  rate_samples_.emplace_back(now, rows_done_total_);
  while (rate_samples_.size() > 2 && now - rate_samples_[1].first > kRateWindow) rate_samples_.pop_front();
}

void StatusBoard::set_worker_endpoint(const std::string& endpoint) {
  std::lock_guard<std::mutex> lock(mutex_);
  worker_endpoint_ = endpoint;
}

void StatusBoard::set_worker_keys(const std::string& broker_public_key, const std::string& allow_dir) {
  std::lock_guard<std::mutex> lock(mutex_);
  broker_public_key_ = broker_public_key;
  allow_dir_ = allow_dir;
}

json StatusBoard::service_json() const {
  std::lock_guard<std::mutex> lock(mutex_);
  if (worker_endpoint_.empty())
    return {{"workers", nullptr}, {"worker_connect", nullptr}, {"worker_command", nullptr}, {"allow", nullptr}};
  const std::string connect = worker_connect_address(worker_endpoint_);
  // The key and allow folders are paths as the command line gave them, which
  // need not be UTF-8, the only text JSON carries: dump() threw on such a
  // byte and the page's every poll was answered 500. Such a byte is written
  // \xNN, as the logs write it (escape_control_characters): U+FFFD in its
  // place named no file the operator could find.
  return {{"workers", escape_control_characters(worker_endpoint_)},
          {"worker_connect", escape_control_characters(connect)},
          {"worker_command", worker_command(connect, broker_public_key_)},
          {"allow", allow_dir_.empty() ? json(nullptr) : json(escape_control_characters(allow_dir_))}};
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
    auto it = std::find_if(jobs_.begin(), jobs_.end(), [job](const Job& j) { return j.id == job; });
    if (it == jobs_.end()) return std::nullopt;
    width = it->width;
    height = it->height;
    rgb = it->rgb;  // encoded outside the lock: the broker thread must not wait on zlib
    done = it->done;
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
  m.task_round_trip = round_trip_;
  return m;
}

}  // namespace rayfarm
