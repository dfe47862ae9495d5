// Loading configs/broker.json; see broker_config.h.
#include "broker/broker_config.h"

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "protocol/json_fields.h"
#include "protocol/messages.h"
#include "tracer/error.h"
#include "tracer/image_memory.h"
#include "protocol/config_file.h"

namespace rayfarm {
namespace {

void read_broker_fields(JsonFields& f, BrokerConfig& c) {
  f.read("bind", c.bind);
  f.read("announce_bind", c.announce_bind);
  f.read("reference_weight", c.reference_weight, 1e-6, 1e6);
  f.read("base_task_rows", c.base_task_rows, 1, 65536);
  f.read("max_task_rows", c.max_task_rows, 1, 65536);
  f.read("min_span_pixels", c.min_span_pixels, 0, 65536);
  f.read("max_image_mib", c.max_image_mib, 0, 1 << 30);
  if (f.has("policy")) {
    std::string name;
    f.read("policy", name);
    c.policy = parse_policy(name, f.key_path("policy"));
  }
  if (f.has("heartbeat")) {
    JsonFields h = f.object("heartbeat");
    h.read("interval_ms", c.heartbeat_ms, 10, 600000);
    h.read("liveness", c.liveness, 1, 100);
    h.finish();
  }
  f.read("min_workers", c.min_workers, 0, 1 << 20);
  f.read("progress_interval_s", c.progress_interval_s, 0.05, 3600);
  f.read("progress", c.progress);
  f.read("key", c.key_file);
  f.read("allow", c.allow_dir);
}

}  // namespace

BrokerConfig load_broker_config(const std::string& path) {
  BrokerConfig c;
  read_config_file(path, [&](JsonFields& f) { read_broker_fields(f, c); });
  resolve_beside_config(path, {&c.key_file, &c.allow_dir});
  return c;
}

BrokerConfig parse_broker_config(const std::string& text, const std::string& name) {
  BrokerConfig c;
  read_config_text(text, name, [&](JsonFields& f) { read_broker_fields(f, c); });
  return c;
}

int task_rows_for(const BrokerConfig& config, double weight) {
  return std::min(nominal_task_rows(policy_options(config), weight), std::max(1, config.max_task_rows));
}

PolicyOptions policy_options(const BrokerConfig& config) {
  PolicyOptions o;
  o.kind = config.policy;
  o.reference_weight = config.reference_weight;
  o.base_task_rows = config.base_task_rows;
  o.max_task_rows = std::max(1, config.max_task_rows);
  o.min_span_pixels = config.min_span_pixels;
  return o;
}

uint64_t max_image_bytes(const BrokerConfig& config) {
  return config.max_image_mib > 0 ? uint64_t(config.max_image_mib) << 20 : physical_memory_bytes();
}

uint64_t max_worker_frame_bytes(const BrokerConfig& config) {
  return std::max<uint64_t>(protocol::kMaxJsonBytes,
                            protocol::result_frame_bytes(config.max_image_width, config.max_task_rows));
}

}  // namespace rayfarm
