// The embedded local farm; see local_farm.h.
#include "broker/local_farm.h"

#include <signal.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <set>
#include <stdexcept>

#include "broker/child_process.h"
#include "broker/open_files.h"

namespace rayfarm {

namespace {

std::vector<LocalWorker> machines_of(const LocalFarmOptions& o) {
  if (!o.machines.empty()) return o.machines;
  std::vector<LocalWorker> out;
  for (int i = 0; i < o.workers; ++i) out.push_back({"local-" + std::to_string(i + 1), o.weight, 1.0});
  return out;
}

std::vector<std::string> worker_args(const LocalFarmOptions& o, const RenderSettings& settings,
                                     const std::string& endpoint, const LocalWorker& m) {
  std::vector<std::string> args = {"worker",
                                   "--connect", endpoint,
                                   "--name", m.name,
                                   "--threads", std::to_string(o.threads),
                                   "--weight", std::to_string(m.weight),
                                   "--credit", std::to_string(o.credit),
                                   "--throttle", std::to_string(m.throttle),
                                   "--heartbeat-ms", std::to_string(o.heartbeat_ms),
                                   "--liveness", std::to_string(o.liveness)};
  if (o.quiet_workers) args.push_back("--quiet");
  // A worker's SIMD cap is its own, not the job's: `render --workers N
  // --max-isa W` passes it on, or the workers ran at full width.
  if (!settings.max_isa.empty()) args.insert(args.end(), {"--max-isa", settings.max_isa});
  return args;
}

// What the broker holds open for each local worker: its two TCP
// connections (tasks, announcements), with room to spare. Under the common
// soft limit of 1024 files, some 500 workers could not all connect and the
// broker, which starts the job when all have, waited for them forever.
constexpr size_t kBrokerFilesPerLocalWorker = 4;

// The worker processes run `EXE worker ...`: anything but rayfarm ignores
// that, and a test binary started as one runs its whole suite, so a farm
// started from the tests without its executable set launched a storm of
// suites. Only a file named rayfarm or rayfarm-* (rayfarm-farm, which
// `rayfarm render --workers` runs as) is run.
std::string checked_worker_executable(const std::string& exe) {
  const std::string name = std::filesystem::path(exe).filename().string();
  if (name == "rayfarm" || name.rfind("rayfarm-", 0) == 0) return exe;
  throw std::invalid_argument("local farm: the worker executable " + exe + " is not rayfarm (its file name is " +
                              name + ", expected rayfarm or rayfarm-*); set LocalFarmOptions::executable to the rayfarm binary");
}

}  // namespace

LocalFarmResult render_local_farm(const std::string& scene_text, const std::string& scene_name,
                                  const RenderSettings& settings, const LocalFarmOptions& options) {
  const std::string exe = checked_worker_executable(options.executable.empty() ? self_executable() : options.executable);
  const std::vector<LocalWorker> machines = machines_of(options);
  const int workers = static_cast<int>(machines.size());
  if (workers < 1) throw std::invalid_argument("render_local_farm: needs at least one worker");
  // A worker process that exits is dropped by its name (Broker::drop_worker):
  // a name shared by two would drop the living one's tasks with the dead one's.
  std::set<std::string> names;
  for (const LocalWorker& m : machines)
    if (!names.insert(m.name).second)
      throw std::invalid_argument("render_local_farm: two workers named '" + m.name + "'");
  reserve_open_files(workers * kBrokerFilesPerLocalWorker + 64,  // + stdio, libraries, the broker's own sockets
                     "a local farm of " + std::to_string(workers) + " workers",
                     "use fewer --workers or raise the limit");
  BrokerConfig cfg;
  cfg.bind = "tcp://127.0.0.1:*";
  cfg.announce_bind = "tcp://127.0.0.1:*";
  cfg.base_task_rows = options.base_task_rows > 0 ? options.base_task_rows
                                                  : std::max(1, settings.height / (16 * workers));
  cfg.max_task_rows = std::max(cfg.max_task_rows, cfg.base_task_rows);
  cfg.max_image_width = settings.width;
  cfg.reference_weight = options.weight;
  cfg.policy = options.policy;
  cfg.heartbeat_ms = options.heartbeat_ms;
  cfg.liveness = options.liveness;
  cfg.min_workers = workers;  // all start together, as after the paper's multicast init
  cfg.progress = options.progress;
  // By default only trouble is worth a line: lost workers, rejected messages.
  LogSink trouble = [](const std::string& line) {
    if (line.find("lost") != std::string::npos || line.find("rejected") != std::string::npos)
      std::fprintf(stderr, "rayfarm: %s\n", line.c_str());
  };
  Broker broker(cfg, options.log ? options.log : trouble);

  std::vector<ChildProcess> children;  // killed and reaped by their destructors on any exit path
  children.reserve(machines.size());
  for (const LocalWorker& m : machines) children.emplace_back(exe, worker_args(options, settings, broker.endpoint(), m));

  const auto start = std::chrono::steady_clock::now();
  std::vector<bool> seen_exited(children.size(), false);
  auto watch = [&](const FarmProgress& progress) {
    if (options.watch) options.watch(progress);
    if (options.deadline_s > 0 &&
        std::chrono::steady_clock::now() - start > std::chrono::duration<double>(options.deadline_s))
      throw std::runtime_error("local farm: the job took longer than " + std::to_string(options.deadline_s) + " s");
    // A child's exit is known here at once (waitpid), where the broker would
    // wait out its heartbeats: its tasks go to the others now. Before the job
    // starts the broker waits for every worker, so one gone then would keep
    // the render waiting forever: that ends it instead.
    for (size_t i = 0; i < children.size(); ++i) {
      if (seen_exited[i] || children[i].running()) continue;
      seen_exited[i] = true;
      const std::string status = describe_status(children[i].status());
      if (progress.job == 0)
        throw std::runtime_error("local worker " + machines[i].name + " exited before the job started (" + status + ")");
      broker.drop_worker(machines[i].name, "exited (" + status + "): lost");
    }
    for (ChildProcess& c : children)
      if (c.running()) return;
    throw std::runtime_error("all " + std::to_string(children.size()) + " local workers exited (first: " +
                             describe_status(children.front().status()) + ")");
  };
  FarmJob job;
  job.scene_text = scene_text;
  job.scene_name = scene_name;
  job.settings = settings;
  FarmResult r = broker.run(job, watch);

  broker.shutdown_workers(0.05);
  wait_for_all_or_kill(children, 3.0);
  LocalFarmResult out;
  out.width = r.width;
  out.height = r.height;
  out.rgb = std::move(r.rgb);
  out.stats = r.stats;
  out.record = std::move(r.record);
  return out;
}

}  // namespace rayfarm
