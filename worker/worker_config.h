// WorkerConfig: one render server of the farm, loaded from JSON
// (configs/workers/*.json) into a struct with in-class defaults; `rayfarm worker`
// options override single fields. Unknown keys are errors naming the key path.
#pragma once

#include <string>

namespace rayfarm {

struct WorkerConfig {
  std::string name;         // "" = hostname-pid
  std::string description;  // free text, e.g. the machine it stands for
  // Relative speed; the paper's SPECfp92 figures (Sun SSC 21.0). The broker cuts
  // tasks of round(weight / reference_weight * base_task_rows) scanlines.
  double weight = 21.0;
  int threads = 0;  // render threads, 0 = all cores
  std::string max_isa;  // caps Embree's kernel width, e.g. "sse4.2" ("" = the CPU's widest)
  int credit = 2;   // tasks kept in flight so the next one is queued when one ends
  // Emulates a slower machine: after each task, sleep (throttle - 1) x its
  // render time, so the task takes `throttle` times as long (1 = full speed).
  double throttle = 1.0;
  int heartbeat_ms = 1000;
  int liveness = 3;  // broker heartbeats missed before reconnecting, until a `welcome` brings the broker's
  int reconnect_initial_ms = 1000;  // Paranoid Pirate back-off: doubles per failure...
  int reconnect_max_ms = 32000;     // ...up to this
  std::string connect;    // broker ROUTER endpoint, e.g. tcp://head:5555
  std::string subscribe;  // broker PUB endpoint; "" = connect host, port from the broker
  bool quiet = false;     // log errors only (command line, not in files)
  // CURVE (protocol/curve_keys.h): this worker's secret key file and the
  // broker's public key file, both or neither. Relative to the config file.
  std::string key_file;
  std::string broker_key_file;
};

// Throws InputError "path: key.path: reason".
WorkerConfig load_worker_config(const std::string& path);
// The same for JSON text that came from `name`.
WorkerConfig parse_worker_config(const std::string& text, const std::string& name);

// Host name and pid, the default worker name.
std::string default_worker_name();

}  // namespace rayfarm
