// StatusBoard: what the status page shows, kept between the broker loop that
// produces it and the HTTP threads that serve it. The broker thread feeds it
// each loop turn (update() with the broker's FarmProgress); it copies only the
// rows accepted since the last turn, so a turn costs a few row copies. The HTTP
// threads read JSON, preview PNGs and metrics from it. One mutex, held briefly.
#pragma once

#include <chrono>
#include <cstdint>
#include <deque>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "broker/broker.h"
#include "status/metrics.h"

namespace rayfarm {

class StatusBoard {
 public:
  // Finished jobs keep their image (for the page's "click a finished job") up
  // to `keep_images` jobs; older ones keep their row counts only.
  explicit StatusBoard(size_t keep_images = 4);

  // ---- broker thread -------------------------------------------------------
  void update(const FarmProgress& p);
  // The job's record once the broker returned it (broker/job_record.h).
  void set_record(uint64_t job, const nlohmann::json& record);

  // ---- HTTP threads --------------------------------------------------------
  // [{id, scene, state: "running" | "done", rows_done, rows_total, width, height}], oldest first.
  nlohmann::json jobs_json() const;
  std::optional<nlohmann::json> job_json(uint64_t job) const;
  std::optional<nlohmann::json> record(uint64_t job) const;
  // [{name, serial, weight, task_rows, rows_per_s, rows_done, tasks_done,
  //   tasks_in_flight, busy_s, last_heard_s, state}]; rows_per_s is rows per
  // busy second over the current job (0 before its first result).
  nlohmann::json workers_json() const;
  // nullopt for a job it never saw or whose image was dropped.
  std::optional<std::string> preview_png(uint64_t job) const;
  // Everything but jobs_by_state, which belongs to whoever owns the job queue.
  FarmMetrics metrics() const;
  // Jobs by state as this board saw them (for a host without a job queue).
  std::map<std::string, int> jobs_by_state() const;

 private:
  using Clock = std::chrono::steady_clock;
  struct Job {
    uint64_t id = 0;
    std::string scene;
    int width = 0, height = 0, rows_done = 0, rows_total = 0;
    std::vector<float> rgb;  // dropped for old finished jobs
    std::vector<bool> done;
    nlohmann::json record;
    bool finished() const { return rows_total > 0 && rows_done == rows_total; }
  };
  Job& job_entry(const FarmProgress& p);
  nlohmann::json summary(const Job& j) const;
  const Job* find(uint64_t job) const;

  size_t keep_images_;
  mutable std::mutex mutex_;
  std::deque<Job> jobs_;
  std::vector<WorkerView> workers_;
  std::map<std::string, int> rejected_;  // of the current job (the broker's count)
  std::map<std::string, uint64_t> rejected_total_;  // summed over jobs
  uint64_t rejected_job_ = 0;
  uint64_t rows_done_total_ = 0;
  std::deque<std::pair<Clock::time_point, uint64_t>> rate_samples_;  // (when, rows_done_total)
  Histogram round_trip_{round_trip_bounds()};
};

}  // namespace rayfarm
