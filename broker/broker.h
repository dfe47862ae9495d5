// Broker: the client side of the farm (`rayfarm broker`, and the local farm of
// `rayfarm render --workers N`). A ROUTER socket serves workers (registration,
// demand-driven scanline tasks with per-worker credit, results, heartbeats) and
// a PUB socket announces jobs to all workers at once. It assembles the image,
// requeues the tasks of workers that fall silent and keeps a job record.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "broker/broker_config.h"
#include "broker/log_sink.h"
#include "broker/task_board.h"
#include "protocol/messages.h"
#include "tracer/ray_stats.h"
#include "tracer/render_settings.h"

namespace rayfarm {

struct FarmJob {
  std::string scene_text;  // NFF; sent to the workers, hashed for their cache
  std::string scene_name;  // for messages ("name:line: ...")
  RenderSettings settings;
  // A job resumed after a broker restart: rows already rendered ([y0, y1)
  // bands, their pixels in `restored_rgb`, laid out as the whole image) are
  // not rendered again.
  std::vector<std::pair<int, int>> restored_rows{};
  std::vector<float> restored_rgb{};
  RayStats restored_stats{};
};

// What a durable caller (the service, service/farm_service.h) hears during a
// job. `sent` runs for each task handed out (rows, or a span of one row).
// `accepted` runs for each result after it is judged valid and BEFORE its
// rows count as done: once it returns the rows must be safe (journaled); if it
// throws, the job ends with that exception. A row cut into pixel spans is
// passed once, whole, with the span that completes it (the rays of all its
// spans): `accepted` only ever sees whole rows.
// `upcoming` is asked once, when a quarter of the rows or fewer are left to
// hand out: the job it names (if any) is announced at once, so workers parse
// its scene and build its BVH (on their load thread) while the last rows
// render, and the next run() of that job starts on workers already loaded.
struct FarmHooks {
  std::function<void(const PixelBand& task)> sent;
  std::function<void(const protocol::TaskResult&)> accepted;
  std::function<std::optional<FarmJob>()> upcoming;
};

struct FarmResult {
  int width = 0, height = 0;
  std::vector<float> rgb;  // width * height * 3, row-major, top row first
  RayStats stats;
  nlohmann::json record;  // see broker/job_record.h
};

// A worker as the status page shows it (status/status_board.h).
struct WorkerView {
  uint32_t serial = 0;
  std::string name;
  double weight = 0;
  int task_rows = 1;
  int tasks = 0, rows = 0;  // accepted during the current job
  double busy_s = 0;        // render + throttle seconds of those tasks
  int in_flight = 0;
  double last_heard_s = 0;  // seconds since its last message; for "lost", since it was dropped
  // "loading" (has not reported job_ready), "rendering" (tasks in flight),
  // "idle", "lost" (heartbeat timeout) or "left" (said bye, re-registered).
  std::string state;
};

// What a watcher sees each turn of the broker loop.
struct FarmProgress {
  uint64_t job = 0;
  int rows_done = 0, rows_total = 0;
  int workers = 0;                         // registered now
  // By registration, "NAME#SERIAL" (broker/job_record.h): two workers may
  // share a name, and a re-registered one is a new entry.
  std::map<std::string, int> tasks_done;
  std::map<std::string, int> rejected;     // by reason
  std::vector<WorkerView> worker_views;    // registered, then those gone during the job
  int rows_restored = 0;                   // done before a broker restart (in rows_done)
  // News since the previous turn: bands [y0, y1) that came into `image`
  // (first the restored ones), and the dispatch-to-result seconds of tasks.
  std::vector<std::pair<int, int>> new_bands;
  std::vector<double> new_round_trips;
  // The job's image so far (width * height * 3 floats), valid during the watch call only.
  const std::vector<float>* image = nullptr;
  int width = 0, height = 0;
  std::string scene_name;
};


// The workers could not render the job: its scene or settings are at fault, or
// two workers failed it (protocol/SPEC.md, `job_failed`). what() has the reason.
struct FarmJobFailed : std::runtime_error {
  using std::runtime_error::runtime_error;
};

class Broker {
 public:
  // Binds both sockets; throws InputError if an endpoint cannot be bound.
  explicit Broker(BrokerConfig config, LogSink log = {});
  ~Broker();
  Broker(const Broker&) = delete;
  Broker& operator=(const Broker&) = delete;

  // The endpoints actually bound (a "*" port resolved), e.g. "tcp://127.0.0.1:41234".
  std::string endpoint() const;
  std::string announce_endpoint() const;

  // Renders `job` with whichever workers are or become registered, after
  // waiting for `config.min_workers`. `watch` runs every 10-60 ms and may
  // throw to abort the job. Throws InputError for settings no worker could
  // render, FarmJobFailed when the workers fail the job.
  FarmResult run(const FarmJob& job, const std::function<void(const FarmProgress&)>& watch = {},
                 const FarmHooks& hooks = {});

  // Serves (registrations, heartbeats) for `seconds` without a job.
  void serve_for(double seconds);

  // Publishes `shutdown` and sends it to every registered worker, then serves
  // for up to `grace_s` so the messages leave.
  void shutdown_workers(double grace_s = 0.3);

  // The worker registered as `name` is known to be gone without a word (a
  // local farm saw its child process exit): every registration of that name
  // is dropped as lost, its tasks requeued now instead of after the heartbeat
  // timeout. The name must be that worker's alone (a local farm's are). `why`
  // ends the log line. Nothing happens if no worker of that name is registered.
  void drop_worker(const std::string& name, const std::string& why);

  size_t worker_count() const;
  // What a watcher of run() would see now (between jobs: the registered workers).
  FarmProgress progress() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace rayfarm
