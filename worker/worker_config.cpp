// Loading configs/workers/*.json; see worker_config.h.
#include "worker/worker_config.h"

#include <unistd.h>

#include <filesystem>

#include "protocol/config_file.h"
#include "tracer/error.h"
#include "tracer/embree_scene.h"

namespace rayfarm {
namespace {

void read_worker_fields(JsonFields& f, WorkerConfig& c) {
  f.read("name", c.name, 128);
  f.read("description", c.description);
  f.read("weight", c.weight, 1e-6, 1e6);
  f.read("threads", c.threads, 0, 4096);
  f.read("max_isa", c.max_isa, 16);
  check_embree_isa(c.max_isa, f.key_path("max_isa"));
  f.read("credit", c.credit, 1, 64);
  f.read("throttle", c.throttle, 1, 1000);
  f.read("connect", c.connect);
  f.read("subscribe", c.subscribe);
  if (f.has("heartbeat")) {
    JsonFields h = f.object("heartbeat");
    h.read("interval_ms", c.heartbeat_ms, 10, 600000);
    h.read("liveness", c.liveness, 1, 100);
    h.finish();
  }
  if (f.has("reconnect")) {
    JsonFields r = f.object("reconnect");
    r.read("initial_ms", c.reconnect_initial_ms, 10, 3600000);
    r.read("max_ms", c.reconnect_max_ms, 10, 3600000);
    if (c.reconnect_initial_ms > c.reconnect_max_ms)
      throw InputError(r.key_path("initial_ms") + ": must be <= reconnect.max_ms (" +
                       std::to_string(c.reconnect_initial_ms) + " > " + std::to_string(c.reconnect_max_ms) + ")");
    r.finish();
  }
  f.read("key", c.key_file);
  f.read("broker_key", c.broker_key_file);
}

}  // namespace

WorkerConfig load_worker_config(const std::string& path) {
  WorkerConfig c;
  read_config_file(path, [&](JsonFields& f) { read_worker_fields(f, c); });
  resolve_beside_config(path, {&c.key_file, &c.broker_key_file});
  return c;
}

WorkerConfig parse_worker_config(const std::string& text, const std::string& name) {
  WorkerConfig c;
  read_config_text(text, name, [&](JsonFields& f) { read_worker_fields(f, c); });
  return c;
}

std::string default_worker_name() {
  char host[256] = "worker";
  gethostname(host, sizeof host - 1);
  return std::string(host) + "-" + std::to_string(getpid());
}

}  // namespace rayfarm
