// Lab files; see lab.h.
#include "worker/lab.h"

#include <cstdio>
#include <filesystem>

#include "protocol/config_file.h"
#include "tracer/error.h"

namespace rayfarm {
namespace {

namespace fs = std::filesystem;

// One entry of "machines": a worker config (or just a weight) plus a count,
// with optional overrides of the config's fields.
LabMachineType read_machine(JsonFields& f, const fs::path& lab_dir) {
  LabMachineType m;
  if (f.has("config")) {
    const std::string config = f.string("config", 1, 4096);
    const fs::path resolved = fs::path(config).is_absolute() ? fs::path(config) : lab_dir / config;
    try {
      m.config = load_worker_config(resolved.string());
    } catch (const InputError& e) {
      throw InputError(f.key_path("config") + ": " + e.what());
    }
    m.name = resolved.stem().string();
  } else if (!f.has("weight")) {
    throw InputError(f.key_path("config") + ": missing (give a worker config or a weight)");
  }
  m.count = static_cast<int>(f.integer("count", 1, kMaxLabMachines));
  f.read("name", m.name, 128);
  f.read("weight", m.config.weight, 1e-6, 1e6);
  f.read("throttle", m.config.throttle, 1, 1000);
  f.read("credit", m.config.credit, 1, 64);
  f.read("speed", m.speed, 1e-9, 1e9);
  f.read("init_s", m.init_s, 0, 1e9);
  f.finish();
  if (m.name.empty()) m.name = "machine";
  return m;
}

}  // namespace

int Lab::machine_count() const {
  int n = 0;
  for (const LabMachineType& t : types) n += t.count;
  return n;
}

Lab load_lab(const std::string& path) {
  Lab lab;
  lab.path = path;
  const fs::path dir = fs::path(path).parent_path();
  read_config_file(path, [&](JsonFields& f) {
    f.read("description", lab.description);
    f.read("reference_weight", lab.reference_weight, 1e-6, 1e6);
    const nlohmann::json& machines = f.array("machines", 1, 10000);
    for (size_t i = 0; i < machines.size(); ++i) {
      JsonFields m(machines[i], f.key_path("machines[" + std::to_string(i) + "]"));
      lab.types.push_back(read_machine(m, dir));
      if (lab.machine_count() > kMaxLabMachines)
        throw InputError(m.key_path("count") + ": the lab would have " + std::to_string(lab.machine_count()) +
                         " machines, more than " + std::to_string(kMaxLabMachines));
    }
  });
  return lab;
}

std::vector<WorkerConfig> lab_workers(const Lab& lab) {
  std::vector<WorkerConfig> out;
  for (const LabMachineType& t : lab.types) {
    for (int k = 1; k <= t.count; ++k) {
      WorkerConfig c = t.config;
      char name[160];
      std::snprintf(name, sizeof name, "%s-%02d", t.name.c_str(), k);
      c.name = name;
      out.push_back(c);
    }
  }
  return out;
}

}  // namespace rayfarm
