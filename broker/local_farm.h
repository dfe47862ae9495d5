// The embedded local farm behind `rayfarm render --workers N`: a broker on
// 127.0.0.1 ephemeral ports in this process and N `rayfarm worker` child
// processes, one job, then everything is shut down -- also on errors, since the
// children are owned (broker/child_process.h). The image is byte-identical to an
// in-process render of the same scene and settings.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "broker/broker.h"
#include "tracer/ray_stats.h"
#include "tracer/render_settings.h"

namespace rayfarm {

// One worker process of a local farm that differs from the others (e.g. an
// emulated older machine).
struct LocalWorker {
  std::string name;
  double weight = 21.0;
  double throttle = 1.0;  // see WorkerConfig::throttle
};

struct LocalFarmOptions {
  int workers = 2;         // identical workers "local-N"; ignored when `machines` is set
  std::vector<LocalWorker> machines;  // one worker process each, names distinct
  int threads = 0;  // per worker, 0 = all cores (they share them)
  std::string executable;  // "" = /proc/self/exe; tests pass the rayfarm binary
  double weight = 21.0;
  int credit = 2;
  // Rows per task; 0 = height / (16 x workers). Local workers are identical
  // multi-core processes: bands of several rows keep all their threads busy
  // (a one-row band parallelises poorly), and 16 tasks per worker still
  // balance the load (Sung, Loh and Ananda suggest ~5 per normalised server).
  int base_task_rows = 0;
  PolicyKind policy = PolicyKind::adaptive;  // broker/dispatch_policy.h
  int heartbeat_ms = 1000;
  int liveness = 3;
  bool progress = true;
  bool quiet_workers = true;  // workers log only errors
  double deadline_s = 0;      // > 0: give up on the job after this many seconds
  LogSink log;                // broker log lines; {} = stderr
  // Runs every broker loop turn after the farm's own checks (e.g. a
  // StatusBoard's update, status/status_board.h); may throw to abort.
  std::function<void(const FarmProgress&)> watch;
};

struct LocalFarmResult {
  int width = 0, height = 0;
  std::vector<float> rgb;
  RayStats stats;
  nlohmann::json record;  // job record (broker/job_record.h)
};

// Renders `scene_text` (NFF, already validated by the caller's parse) with
// `settings`. A worker process that exits during the job is dropped at once,
// its tasks requeued. Throws std::runtime_error if one exits before the job
// starts, or all of them before it ends.
LocalFarmResult render_local_farm(const std::string& scene_text, const std::string& scene_name,
                                  const RenderSettings& settings, const LocalFarmOptions& options);

}  // namespace rayfarm
