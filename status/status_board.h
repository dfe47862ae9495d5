// StatusBoard: what the status page shows live, kept between the broker loop
// that produces it and the HTTP threads that serve it. The broker thread feeds
// it each loop turn (update() with the broker's FarmProgress); it copies only
// the rows accepted since the last turn, so a turn costs a few row copies. The
// HTTP threads read the worker table, job previews and metrics. One mutex, held
// briefly; PNG encoding happens outside it.
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

// What a worker passes to --connect to reach a socket bound to `endpoint`:
// the address itself, but for one bound to every interface ("tcp://0.0.0.0:
// 5555", "tcp://[::]:5555"), which no worker can connect to: "tcp://HEAD:5555",
// HEAD for the head node's name.
std::string worker_connect_address(const std::string& endpoint);

// The public key file a keyed farm's workers pass to --broker-key: NAME.pub
// beside the broker's NAME.key, as `rayfarm keygen -o NAME` writes them, or
// "BROKER.pub" for a key file named otherwise. Never the secret key's path.
std::string broker_public_key_beside(const std::string& broker_key_file);

// The whole `rayfarm worker` command the page suggests: --connect `connect`,
// and on a keyed farm (`broker_public_key` non-empty) the two key options a
// worker cannot connect without, its own key as the placeholder WORKER.key.
// Paths a shell would split are quoted; one holding a byte that is not UTF-8
// or a control character is written $'...' with the log text's escapes.
std::string worker_command(const std::string& connect, const std::string& broker_public_key);

class StatusBoard {
 public:
  // The newest `keep_images` jobs keep their image for the page.
  explicit StatusBoard(size_t keep_images = 4);

  // ---- broker thread -------------------------------------------------------
  // `job`: the id the API knows the job by (the service's job id; a job of
  // several frames shows its current frame); 0 = the broker's own id. Between
  // jobs, pass the broker's progress() to keep the worker table current.
  void update(const FarmProgress& p, uint64_t job = 0);
  // The worker socket as bound (Broker::endpoint(), e.g. "tcp://0.0.0.0:5555"),
  // once it is: the page tells how to start a worker with its real port.
  void set_worker_endpoint(const std::string& endpoint);
  // A keyed farm (broker --key/--allow): the broker's public key file
  // (broker_public_key_beside()) and the folder of invited workers' *.pub,
  // for the hint. Unset: a farm without keys.
  void set_worker_keys(const std::string& broker_public_key, const std::string& allow_dir);

  // ---- HTTP threads --------------------------------------------------------
  // [{name, serial, weight, task_rows, rows_per_s, rows_done, tasks_done,
  //   tasks_in_flight, busy_s, last_heard_s, state}]; rows_per_s is rows per
  // busy second over the current job, or the last one between jobs.
  nlohmann::json workers_json() const;
  // The job's image so far (status/preview.h); nullopt for a job this board
  // never saw or no longer keeps.
  std::optional<std::string> preview_png(uint64_t job) const;
  // Everything but jobs_by_state, which belongs to the job queue.
  FarmMetrics metrics() const;
  // {workers, worker_connect, worker_command, allow}: worker_connect_address(),
  // worker_command(), and the allow folder a worker's public key goes in (null
  // on a farm without keys); all null until the worker socket is bound. A
  // byte of a path that is not UTF-8 is given as \xNN, as the logs give it.
  nlohmann::json service_json() const;

 private:
  using Clock = std::chrono::steady_clock;
  struct Job {
    uint64_t id = 0;
    uint64_t broker_job = 0;  // the frame being rendered, by the broker's id
    int width = 0, height = 0, rows_done = 0;
    std::vector<float> rgb;
    std::vector<bool> done;
  };
  Job& job_entry(uint64_t id, const FarmProgress& p);

  size_t keep_images_;
  mutable std::mutex mutex_;
  std::deque<Job> jobs_;  // oldest first
  std::vector<WorkerView> workers_;
  std::string worker_endpoint_;  // "" until set
  std::string broker_public_key_, allow_dir_;  // "" on a farm without keys
  std::map<std::string, int> rejected_seen_;        // the broker's counts at the last turn
  uint64_t rejected_job_ = 0;                       // the broker job they belong to
  std::map<std::string, uint64_t> rejected_total_;  // since this board started
  uint64_t rows_done_total_ = 0;
  std::deque<std::pair<Clock::time_point, uint64_t>> rate_samples_;  // (when, rows_done_total)
  Histogram round_trip_{round_trip_bounds()};
};

}  // namespace rayfarm
