// `rayfarm worker`: one render server. Loads a JSON config (configs/workers/),
// lets the command line override single fields, and serves the broker until it
// says shutdown or the process gets SIGINT/SIGTERM, or SIGHUP when its terminal
// or ssh session closes (unless it started with them ignored, e.g. under nohup);
// a second one while it stops (a BVH build it waits for) ends it at once.
#include <csignal>
#include <thread>
#include <vector>

#include "app/commands.h"
#include "app/finite_number.h"
#include "tracer/embree_scene.h"
#include "tracer/error.h"
#include "tracer/stop_signals.h"
#include "worker/lab.h"
#include "worker/lab_process.h"
#include "worker/worker.h"
#include "worker/worker_config.h"

namespace rayfarm::cmd {
namespace {

std::atomic<bool> g_stop{false};
extern "C" void on_stop_signal(int) { g_stop = true; }

}  // namespace

void add_worker(CLI::App& app) {
  auto* sub = app.add_subcommand("worker", "serve a rayfarm broker: render the scanline tasks it hands out");
  struct Options {
    std::string config, lab, connect, subscribe, name, max_isa, key, broker_key;
    double weight = 0, throttle = 0;
    int threads = -1, credit = 0, heartbeat_ms = 0, liveness = 0;
    bool quiet = false;
  };
  auto o = std::make_shared<Options>();
  sub->add_option("--config", o->config, "worker config JSON (configs/workers/*.json)")->check(CLI::ExistingFile);
  sub->add_option("--lab", o->lab, "run every machine of a lab file (configs/labs/) as a throttled worker")
      ->check(CLI::ExistingFile)
      ->excludes("--config");
  sub->add_option("--connect", o->connect, "broker endpoint, e.g. tcp://head:5555");
  sub->add_option("--subscribe", o->subscribe, "broker announce endpoint (default: connect host, port from broker)");
  // A lab names each of its machines (<type>-NN): a --name beside it was dropped without a word.
  sub->add_option("--name", o->name, "worker name in logs and job records (default: host-pid)")->excludes("--lab");
  sub->add_option("--weight", o->weight, "relative speed, e.g. SPECfp92 (task size scales with it)")
      ->check(finite_number(1e-6, 1e6));
  sub->add_option("--threads", o->threads, "render threads, 0 = all cores")->check(CLI::Range(0, 4096));
  sub->add_option("--max-isa", o->max_isa,
                  "cap the SIMD kernel width (Embree's and rayfarm's): sse2, sse4.2, avx, avx2 or avx512");
  sub->add_option("--credit", o->credit, "tasks kept in flight")->check(CLI::Range(1, 64));
  sub->add_option("--throttle", o->throttle, "run this many times slower (emulates an older machine)")
      ->check(finite_number(1, 1000));
  sub->add_option("--heartbeat-ms", o->heartbeat_ms, "heartbeat interval")->check(CLI::Range(10, 600000));
  sub->add_option("--liveness", o->liveness,
                  "missed broker heartbeats before reconnecting, until a broker answers (then the broker's own); 1 counts as 2")
      ->check(CLI::Range(1, 100));
  sub->add_option("--key", o->key, "this worker's CURVE secret key file (rayfarm keygen -o NAME: NAME.key)");
  sub->add_option("--broker-key", o->broker_key, "the broker's CURVE public key file (its NAME.pub)");
  sub->add_flag("--quiet", o->quiet, "log errors only");
  sub->callback([o] {
    // The file (or lab) first, then whatever the command line says.
    auto apply = [&](WorkerConfig& cfg) {
      if (!o->connect.empty()) cfg.connect = o->connect;
      if (!o->subscribe.empty()) cfg.subscribe = o->subscribe;
      if (o->weight > 0) cfg.weight = o->weight;
      if (o->throttle > 0) cfg.throttle = o->throttle;
      if (o->threads >= 0) cfg.threads = o->threads;
      if (!o->max_isa.empty()) {
        check_embree_isa(o->max_isa, "--max-isa");
        cfg.max_isa = o->max_isa;
      }
      if (o->credit > 0) cfg.credit = o->credit;
      if (o->heartbeat_ms > 0) cfg.heartbeat_ms = o->heartbeat_ms;
      if (o->liveness > 0) cfg.liveness = o->liveness;
      if (!o->key.empty()) cfg.key_file = o->key;
      if (!o->broker_key.empty()) cfg.broker_key_file = o->broker_key;
      cfg.quiet = o->quiet;
      if (cfg.connect.empty()) throw InputError("worker: no broker endpoint; give --connect tcp://HOST:PORT");
    };
    // Not a signal the process started with ignored (stop_signals.h): a local
    // farm's workers inherit SIGINT ignored from `render --workers`, which
    // carries on through a Ctrl-C meant for the script. SIGHUP too: a worker
    // started from an ssh session died with it, silently, and the broker
    // learnt of it only after its heartbeats ran out; now it says bye first.
    handle_stop_signals(on_stop_signal);
    if (!o->lab.empty()) {
      std::vector<WorkerConfig> machines = lab_workers(load_lab(o->lab));
      for (WorkerConfig& cfg : machines) apply(cfg);
      if (const int code = run_lab_process(machines, g_stop); code != 0) std::exit(code);
      return;
    }
    WorkerConfig cfg = o->config.empty() ? WorkerConfig{} : load_worker_config(o->config);
    if (!o->name.empty()) cfg.name = o->name;
    apply(cfg);
    // The worker checks that the keys go together, in the options' words; a
    // lone key that came from the file is named as the file says it.
    if (cfg.key_file.empty() != cfg.broker_key_file.empty() && o->key.empty() && o->broker_key.empty())
      throw InputError(o->config + (cfg.broker_key_file.empty()
                                        ? ": \"key\" needs \"broker_key\" (the broker's public key file) or --broker-key"
                                        : ": \"broker_key\" needs \"key\" (this worker's secret key file) or --key"));
    Worker worker(cfg);
    const int code = worker.run(g_stop);
    if (code != 0) std::exit(code);
  });
}

}  // namespace rayfarm::cmd
