// Loading configs/broker.json; see broker_config.h.
#include "broker/broker_config.h"

#include <algorithm>
#include <cmath>

#include "protocol/json_fields.h"
#include "protocol/messages.h"
#include "tracer/error.h"
#include "protocol/config_file.h"

namespace rayfarm {

BrokerConfig load_broker_config(const std::string& path) {
  BrokerConfig c;
  read_config_file(path, [&](JsonFields& f) {
    f.read("bind", c.bind);
    f.read("announce_bind", c.announce_bind);
    f.read("reference_weight", c.reference_weight, 1e-6, 1e6);
    f.read("base_task_rows", c.base_task_rows, 1, 65536);
    f.read("max_task_rows", c.max_task_rows, 1, 65536);
    if (f.has("heartbeat")) {
      JsonFields h = f.object("heartbeat");
      h.read("interval_ms", c.heartbeat_ms, 10, 600000);
      h.read("liveness", c.liveness, 1, 100);
      h.finish();
    }
    f.read("min_workers", c.min_workers, 0, 1 << 20);
    f.read("progress_interval_s", c.progress_interval_s, 0.05, 3600);
    f.read("progress", c.progress);
  });
  return c;
}

int task_rows_for(const BrokerConfig& config, double weight) {
  const double rows = std::round(weight / config.reference_weight * config.base_task_rows);
  return static_cast<int>(std::clamp(rows, 1.0, static_cast<double>(std::max(1, config.max_task_rows))));
}

uint64_t max_worker_frame_bytes(const BrokerConfig& config) {
  return std::max<uint64_t>(protocol::kMaxJsonBytes,
                            protocol::result_frame_bytes(config.max_image_width, config.max_task_rows));
}

}  // namespace rayfarm
