// `rayfarm broker`: the head node of a farm. Binds the worker and announce
// sockets, renders one scene with whichever workers connect (`rayfarm worker
// --connect ...` on each machine), writes the image and the job record. The job
// is prepared exactly as `rayfarm render` prepares it (broker/farm_render_job.h).
// With --serve it is the long-running service instead (service/farm_service.h):
// jobs come from its HTTP API and its state folder, until SIGINT/SIGTERM (or
// SIGHUP: its terminal or ssh session closed, unless started under nohup);
// a second one while it stops ends it at once (tracer/stop_signals.h).
#include <sys/resource.h>

#include <atomic>
#include <csignal>
#include <cstddef>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "app/commands.h"
#include "app/finite_number.h"
#include "app/image_options.h"
#include "broker/broker_config.h"
#include "broker/farm_render_job.h"
#include "broker/open_files.h"
#include "broker/log_sink.h"
#include "service/farm_service.h"
#include "service/folder_lock.h"
#include "tracer/error.h"
#include "tracer/interrupt_cleanup.h"
#include "tracer/stop_signals.h"

namespace rayfarm::cmd {
namespace {

std::atomic<bool> g_serve_stop{false};
std::atomic<int> g_serve_signal{0};  // the signal that stopped the service, for its last log line
extern "C" void on_serve_stop_signal(int signal) {
  g_serve_signal = signal;
  g_serve_stop = true;
}

struct ServeCommand {
  bool serve = false;
  std::string state_dir, http = "127.0.0.1:8080", token_file;
  size_t http_connections = kDefaultMaxConnections;
};

void serve(const ServeCommand& c, const BrokerConfig& config) {
  ServeOptions options;
  options.broker = config;
  options.state_dir = c.state_dir;
  options.http = parse_http_address(c.http);
  if (!c.token_file.empty()) options.http.token = read_token_file(c.token_file);
  options.http.max_connections = c.http_connections;
  options.stop = &g_serve_stop;
  // SIGHUP too: a closed terminal or ssh session killed the service by the
  // default action, with no stop line in the log and the frame's last journal
  // write cut short. A signal it started with ignored (`nohup`, a script's
  // background job) stays ignored, as a worker's does; SIGHUP reloads nothing.
  // Taken before the state folder is opened: a start waiting for a folder
  // another broker holds was killed by the default action, without a word.
  // A second signal ends it at once, its state as a kill -9 leaves it.
  handle_stop_signals(on_serve_stop_signal);
  std::optional<FarmService> service;
  try {
    service.emplace(options);
  } catch (const LockWaitStopped& e) {
    write_log({}, "stopping on " + std::string(stop_signal_name(g_serve_signal)) + " " + e.what());
    return;
  }
  service->run(g_serve_stop);
  if (g_serve_signal) service->log_stop(stop_signal_name(g_serve_signal));
}

// Each worker holds two connections to the broker (tasks, announcements):
// four files, with room to spare.
constexpr size_t kBrokerFilesPerWorker = 4;

// A broker takes every worker that connects. Under the common soft limit of
// 1024 open files some 500 could; the rest never registered, and a broker
// waiting for --min-workers of them waited forever without a word. So the
// soft limit goes up to the hard one, which must hold the workers waited for.
void reserve_worker_files(const BrokerConfig& cfg, const std::string& min_workers_source) {
  open_files_up_to_hard_limit(static_cast<size_t>(cfg.min_workers) * kBrokerFilesPerWorker + 64,
                              "a broker waiting for " + std::to_string(cfg.min_workers) + " workers (" +
                                  min_workers_source + ")",
                              "wait for fewer workers or raise the hard limit (`ulimit -Hn`, or LimitNOFILE= of "
                              "a systemd service)");
}

// Each HTTP connection holds an open file. With --http-connections above what
// the open-file limit leaves beside the workers and the broker's own files,
// the cap never answered 503: clients took every file, and the state folder
// failed to write ("last-id: cannot write (Too many open files)"), a
// submission with it. The soft limit is already raised to the hard one
// (reserve_worker_files); a cap the hard limit cannot hold is refused at start.
void reserve_http_files(const ServeCommand& c, const BrokerConfig& config) {
  const size_t own = static_cast<size_t>(config.min_workers) * kBrokerFilesPerWorker + 64;
  rlimit limit{};
  const bool bounded = getrlimit(RLIMIT_NOFILE, &limit) == 0 && limit.rlim_max != RLIM_INFINITY;
  const std::string fits = bounded && limit.rlim_max >= own + 2
                               ? "give --http-connections " + std::to_string(limit.rlim_max - own) + " or fewer"
                               : "give a smaller --http-connections";
  reserve_open_files(c.http_connections + own,
                     "an HTTP API of " + std::to_string(c.http_connections) + " connections (--http-connections)" +
                         (config.min_workers > 0 ? " beside " + std::to_string(config.min_workers) + " worker" +
                                                       (config.min_workers > 1 ? "s" : "") + " waited for"
                                                 : ""),
                     fits + " or raise the hard limit (`ulimit -Hn`, or LimitNOFILE= of a systemd service)");
}

}  // namespace

void add_broker(CLI::App& app) {
  auto* sub = app.add_subcommand("broker", "render a scene on a farm of `rayfarm worker` processes");
  struct Options {
    RenderJob job;
    ImageOptions image;
    BrokerJobOptions farm;
    std::string config, bind, announce, key, allow, policy;
    int base_rows = 0, min_workers = -1, heartbeat_ms = 0, liveness = 0;
    double reference_weight = 0;
    bool no_progress = false, insecure = false;
  };
  auto o = std::make_shared<Options>();
  auto service = std::make_shared<ServeCommand>();
  RenderOverrides& r = o->job.overrides;
  sub->add_option("scene", o->job.scene_path, "NFF scene file (one-shot mode)");
  sub->add_option("-o,--output", o->job.output_path, "output image: .png/.tif (8-bit, linear) or .exr (float)");
  sub->add_flag("--serve", service->serve, "run as a service: take jobs over HTTP until stopped (docs/deployment.md)");
  // Options of one mode only: given in the other, they are refused rather than ignored.
  const std::vector<CLI::Option*> serve_only = {
      sub->add_option("--state", service->state_dir, "with --serve: the state folder (jobs, journal, images)"),
      sub->add_option("--http", service->http, "with --serve: HTTP API address HOST:PORT (port 0 = any)")
          ->capture_default_str(),
      sub->add_option("--token-file", service->token_file,
                      "with --serve: bearer token the API requires (needed beyond loopback)")
          ->check(CLI::ExistingFile),
      sub->add_option("--http-connections", service->http_connections,
                      "with --serve: HTTP connections open at once, one client address at most half; more are "
                      "answered 503 (must fit the open-file limit, `ulimit -Hn`)")
          ->capture_default_str()
          ->check(CLI::Range(2, 1 << 20))};
  // Options of one job only, each with what the service does instead.
  std::vector<std::pair<CLI::Option*, std::string>> one_shot_only = {
      {sub->add_option("--stats", o->job.stats_path, "write render statistics as JSON to this file"),
       "the service keeps each frame's job record, its ray counts and times included, in DIR/jobs/ID/"}};
  sub->add_option("--config", o->config, "broker config JSON (configs/broker.json)");
  one_shot_only.emplace_back(sub->add_option("--record", o->farm.record_path, "write the job record (JSON) here"),
                             "the service keeps each frame's job record in DIR/jobs/ID/");
  sub->add_option("--bind", o->bind, "worker endpoint to bind (default tcp://*:5555)");
  sub->add_option("--announce", o->announce, "announce endpoint to bind (default tcp://*:5556)");
  o->image.add_to(sub, r);
  sub->add_option("--base-rows", o->base_rows, "scanlines per task at the reference weight")->check(CLI::Range(1, 65536));
  sub->add_option("--policy", o->policy, std::string("dispatch policy: ") + kPolicyNames + " (default adaptive)");
  sub->add_option("--reference-weight", o->reference_weight, "weight that gets base-rows per task")
      ->check(finite_number(1e-6, 1e6));
  sub->add_option("--min-workers", o->min_workers, "workers to wait for before starting")->check(CLI::Range(0, 1 << 20));
  sub->add_option("--heartbeat-ms", o->heartbeat_ms,
                  "how often the broker tells workers it is alive (a worker is lost after --liveness of its own "
                  "heartbeat intervals, which it sets)")
      ->check(CLI::Range(10, 600000));
  sub->add_option("--liveness", o->liveness, "missed heartbeats before a worker is lost (1 counts as 2: a peer heartbeats only after a quiet interval)")->check(CLI::Range(1, 100));
  sub->add_option("--key", o->key, "the broker's CURVE secret key file (rayfarm keygen -o NAME: NAME.key)");
  sub->add_option("--allow", o->allow, "folder of invited workers' public keys: every *.pub in it is admitted");
  sub->add_flag("--insecure", o->insecure, "without keys, admit any host (default: loopback peers only)");
  one_shot_only.emplace_back(
      sub->add_flag("--shutdown-workers", o->farm.shutdown_workers, "tell the workers to exit when done"),
      "the service keeps its workers from job to job; stop a worker on its own machine (SIGTERM, systemctl stop)");
  sub->add_flag("--no-progress", o->no_progress, "no progress line");
  sub->callback([o, service, serve_only, one_shot_only] {
    BrokerConfig& cfg = o->farm.config;
    if (!o->config.empty()) cfg = load_broker_config(o->config);
    if (!o->bind.empty()) cfg.bind = o->bind;
    if (!o->announce.empty()) cfg.announce_bind = o->announce;
    if (o->base_rows > 0) cfg.base_task_rows = o->base_rows;
    if (o->reference_weight > 0) cfg.reference_weight = o->reference_weight;
    if (!o->policy.empty()) cfg.policy = parse_policy(o->policy, "--policy");
    if (o->min_workers >= 0) cfg.min_workers = o->min_workers;
    if (o->heartbeat_ms > 0) cfg.heartbeat_ms = o->heartbeat_ms;
    if (o->liveness > 0) cfg.liveness = o->liveness;
    if (o->no_progress) cfg.progress = false;
    if (!o->key.empty()) cfg.key_file = o->key;
    if (!o->allow.empty()) cfg.allow_dir = o->allow;
    cfg.insecure = o->insecure;
    // The broker checks that key and allow go together, in the options' words;
    // a lone one that came from the file is named as the file says it.
    if (cfg.key_file.empty() != cfg.allow_dir.empty() && o->key.empty() && o->allow.empty())
      throw InputError(o->config + (cfg.allow_dir.empty()
                                        ? ": \"key\" needs \"allow\" (the invited workers' *.pub files) or --allow DIR"
                                        : ": \"allow\" needs \"key\" (the broker's own secret key) or --key FILE"));
    reserve_worker_files(cfg, o->min_workers >= 0 ? "--min-workers"
                              : o->config.empty() ? "by default"
                                                  : "min_workers in " + o->config);
    if (service->serve) {
      if (!o->job.scene_path.empty() || !o->job.output_path.empty())
        throw InputError("broker --serve takes jobs over HTTP (rayfarm submit), not a scene on its command line");
      if (o->image.any_given())
        throw InputError("broker --serve: each job brings its own image options; give --width, --spp, ... to "
                         "rayfarm submit");
      for (const auto& [opt, instead] : one_shot_only)
        if (opt->count())
          throw InputError("broker --serve: " + opt->get_name() +
                           " is an option of one job (broker SCENE -o OUT), not of the service; " + instead);
      if (service->state_dir.empty()) throw InputError("broker --serve needs --state DIR");
      reserve_http_files(*service, cfg);
      return serve(*service, cfg);
    }
    if (o->job.scene_path.empty() || o->job.output_path.empty())
      throw InputError("broker: give SCENE -o OUT for one job, or --serve --state DIR for the service");
    for (const CLI::Option* opt : serve_only)
      if (opt->count()) throw InputError("broker: " + opt->get_name() + " goes with --serve (the service)");
    o->image.apply_size(o->job.overrides);

    o->farm.listening = [](const Broker& broker) {
      std::fprintf(stderr, "rayfarm broker: workers connect to %s (announcements on %s)\n",
                   broker.endpoint().c_str(), broker.announce_endpoint().c_str());
    };
    RenderCallbacks callbacks;
    callbacks.warning = [](const std::string& w) { std::fprintf(stderr, "warning: %s\n", w.c_str()); };
    remove_temporaries_on_interrupt();  // no temporary of -o, --stats or --record left by Ctrl-C
    const RenderReport report = run_render_job_on_broker(o->job, o->farm, callbacks);
    std::fprintf(stderr, "rayfarm broker: wrote %s (%.2f s)\n", o->job.output_path.c_str(), report.seconds.render);
  });
}

}  // namespace rayfarm::cmd
