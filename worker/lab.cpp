// Lab files; see lab.h.
#include "worker/lab.h"

#include <cstdio>
#include <filesystem>

#include "tracer/error.h"
#include "protocol/config_file.h"

namespace rayfarm {

std::vector<WorkerConfig> load_lab_workers(const std::string& path) {
  std::vector<WorkerConfig> out;
  const std::filesystem::path dir = std::filesystem::path(path).parent_path();
  read_config_file(path, [&](JsonFields& f) {
    std::string description;
    double reference_weight = 0;  // documents the normalisation; the broker config applies it
    f.read("description", description);
    f.read("reference_weight", reference_weight, 1e-6, 1e6);
    const nlohmann::json& machines = f.array("machines", 1, 10000);
    for (size_t i = 0; i < machines.size(); ++i) {
      JsonFields m(machines[i], f.key_path("machines[" + std::to_string(i) + "]"));
      // A machine is a worker config file, or just a weight (the replay's format).
      std::string config, type = "machine";
      double weight = 0, throttle = 1, replay_only = 0;
      int credit = 0;
      m.read("config", config);
      m.read("weight", weight, 1e-6, 1e6);
      m.read("name", type, 100);
      m.read("credit", credit, 1, 64);
      const int count = static_cast<int>(m.integer("count", 1, 100000));
      m.read("throttle", throttle, 1, 1000);
      m.read("speed", replay_only, 0, 1e6);   // replay model knobs (replay/lab.h):
      m.read("init_s", replay_only, -1, 1e6);  // a real worker measures these itself
      m.finish();
      WorkerConfig base;
      if (!config.empty()) {
        const std::filesystem::path config_path = dir / config;
        base = load_worker_config(config_path.string());
        if (!m.has("name")) type = config_path.stem().string();
      }
      if (weight > 0) base.weight = weight;
      if (credit > 0) base.credit = credit;
      for (int k = 1; k <= count; ++k) {
        WorkerConfig c = base;
        char name[160];
        std::snprintf(name, sizeof name, "%s-%02d", type.c_str(), k);
        c.name = name;
        c.throttle = throttle;
        out.push_back(c);
      }
    }
  });
  return out;
}

}  // namespace rayfarm
