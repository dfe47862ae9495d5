// Lab files; see lab.h.
#include "worker/lab.h"

#include <cstdio>
#include <filesystem>

#include "tracer/error.h"
#include "worker/config_file.h"

namespace rayfarm {

std::vector<WorkerConfig> load_lab(const std::string& path) {
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
      const std::string config = m.string("config", 1, 4096);
      const int count = static_cast<int>(m.integer("count", 1, 100000));
      double throttle = 1;
      m.read("throttle", throttle, 1, 1000);
      m.finish();
      const std::filesystem::path config_path = dir / config;
      const WorkerConfig base = load_worker_config(config_path.string());
      for (int k = 1; k <= count; ++k) {
        WorkerConfig c = base;
        char name[160];
        std::snprintf(name, sizeof name, "%s-%02d", config_path.stem().string().c_str(), k);
        c.name = name;
        c.throttle = throttle;
        out.push_back(c);
      }
    }
  });
  return out;
}

}  // namespace rayfarm
