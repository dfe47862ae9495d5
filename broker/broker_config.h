// BrokerConfig: how `rayfarm broker` listens and cuts work, loaded from JSON
// (configs/broker.json) into a struct with in-class defaults; the command line
// overrides single fields afterwards. Unknown keys are errors naming the key path.
#pragma once

#include <cstdint>
#include <string>

#include "broker/dispatch_policy.h"

namespace rayfarm {

struct BrokerConfig {
  std::string bind = "tcp://*:5555";           // ROUTER: workers connect here
  std::string announce_bind = "tcp://*:5556";  // PUB: job announcements, shutdown
  // Task size for a worker = max(1, round(weight / reference_weight * base_task_rows)).
  // The paper's lab normalised to the Sun SPARCclassic, SPECfp92 21.0.
  double reference_weight = 21.0;
  int base_task_rows = 1;  // the paper found one scanline per task best
  // No task is taller, whatever the weight: with the widest image this bounds
  // the largest legitimate result frame, and so ZMQ_MAXMSGSIZE on the ROUTER.
  int max_task_rows = 256;
  // The widest job this broker will run (not a file key: `rayfarm broker` and
  // the local farm set it to their job's width before binding).
  int max_image_width = 65536;
  // The largest frame this broker takes: it holds the whole float image (12
  // bytes a pixel) while the frame renders. 0 = this machine's physical memory.
  int max_image_mib = 0;
  PolicyKind policy = PolicyKind::adaptive;  // broker/dispatch_policy.h
  // adaptive: the narrowest pixel span a tail row is cut into; 0 = whole rows only.
  int min_span_pixels = PolicyOptions{}.min_span_pixels;
  int heartbeat_ms = 1000;
  int liveness = 3;  // heartbeats a worker may miss before its tasks are requeued
  int min_workers = 1;  // registered workers to wait for before announcing a job
  double progress_interval_s = 5;  // period of the plain progress line (non-TTY)
  bool progress = true;
  // Security (broker/admission.h): the broker's secret key and a folder of
  // invited workers' *.pub files, both or neither. Without keys only loopback
  // peers are admitted, unless `insecure` (command line only).
  std::string key_file;
  std::string allow_dir;
  bool insecure = false;
};

// Throws InputError "path: key.path: reason". "key" and "allow" are relative
// to the config file's folder.
BrokerConfig load_broker_config(const std::string& path);
// The same for JSON text that came from `name`.
BrokerConfig parse_broker_config(const std::string& text, const std::string& name);

// Rows per task for a worker of `weight` under the configured policy (0: sized
// per task), never above max_task_rows.
int task_rows_for(const BrokerConfig& config, double weight);

PolicyOptions policy_options(const BrokerConfig& config);

// max_image_mib in bytes, or this machine's physical memory for 0.
uint64_t max_image_bytes(const BrokerConfig& config);

// The largest frame a worker may send this broker: a result of max_task_rows
// rows of max_image_width pixels, or a 1 MiB JSON frame if that is larger.
uint64_t max_worker_frame_bytes(const BrokerConfig& config);

}  // namespace rayfarm
