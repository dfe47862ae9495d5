// Lab files and their expansion into machines; see lab.h.
#include "replay/lab.h"

#include <filesystem>

#include "protocol/json_fields.h"
#include "replay/json_file.h"
#include "tracer/error.h"
#include "worker/worker_config.h"

namespace rayfarm {
namespace {

namespace fs = std::filesystem;

// One entry of "machines": a worker config plus count, with optional overrides.
MachineType read_machine(const nlohmann::json& entry, const std::string& key_path, const fs::path& lab_dir) {
  JsonFields f(entry, key_path);
  MachineType m;
  if (f.has("config")) {
    const std::string config = f.string("config", 1, 4096);
    const fs::path resolved = fs::path(config).is_absolute() ? fs::path(config) : lab_dir / config;
    WorkerConfig wc;
    try {
      wc = load_worker_config(resolved.string());
    } catch (const InputError& e) {
      throw InputError(f.key_path("config") + ": " + e.what());
    }
    m.name = resolved.stem().string();
    m.description = wc.description;
    m.weight = wc.weight;
    m.credit = wc.credit;
    m.throttle = wc.throttle;
  } else if (!f.has("weight")) {
    throw InputError(f.key_path("config") + ": missing (give a worker config or a weight)");
  }
  m.count = static_cast<int>(f.integer("count", 1, 1 << 20));
  f.read("name", m.name, 128);
  f.read("weight", m.weight, 1e-6, 1e6);
  f.read("throttle", m.throttle, 1, 1000);
  f.read("speed", m.speed, 1e-9, 1e9);
  f.read("credit", m.credit, 1, 64);
  f.read("init_s", m.init_s, 0, 1e9);
  f.finish();
  if (m.name.empty()) m.name = "machine";
  return m;
}

}  // namespace

int Lab::machine_count() const {
  int n = 0;
  for (const MachineType& t : types) n += t.count;
  return n;
}

Lab load_replay_lab(const std::string& path) {
  const nlohmann::json j = read_json_file(path);
  try {
    if (!j.is_object()) throw InputError("document: expected a JSON object");
    Lab lab;
    lab.path = path;
    nlohmann::json rest = j;
    rest.erase("machines");
    JsonFields f(rest);
    f.read("description", lab.description);
    f.read("reference_weight", lab.reference_weight, 1e-6, 1e6);
    f.finish();
    auto machines = j.find("machines");
    if (machines == j.end()) throw InputError("machines: missing");
    if (!machines->is_array() || machines->empty()) throw InputError("machines: expected a non-empty array");
    const fs::path dir = fs::path(path).parent_path();
    for (size_t i = 0; i < machines->size(); ++i)
      lab.types.push_back(read_machine((*machines)[i], "machines[" + std::to_string(i) + "]", dir));
    return lab;
  } catch (const InputError& e) {
    throw InputError(path + ": " + e.what());
  }
}

std::vector<SimMachine> expand_lab(const Lab& lab, const LabModel& model) {
  std::vector<SimMachine> out;
  for (const MachineType& t : lab.types) {
    SimMachine m;
    m.type = t.name;
    m.weight = t.weight;
    m.credit = t.credit;
    if (t.speed > 0)
      m.speed = t.speed;
    else
      m.speed = model.speed_from == SpeedFrom::weight ? t.weight / lab.reference_weight : 1.0 / t.throttle;
    // BVH build is CPU work too: a machine twice as fast builds twice as fast.
    m.init_s = t.init_s >= 0 ? t.init_s : model.init_s / m.speed;
    for (int i = 0; i < t.count; ++i) {
      m.name = t.name + "-" + std::to_string(i + 1);
      out.push_back(m);
    }
  }
  return out;
}

std::vector<SimMachine> reference_machines(const std::vector<SimMachine>& machines, double reference_weight) {
  std::vector<SimMachine> out;
  for (const SimMachine& m : machines)
    if (m.weight == reference_weight) out.push_back(m);
  return out;
}

double normalized_count(const std::vector<SimMachine>& machines) {
  double n = 0;
  for (const SimMachine& m : machines) n += m.speed;
  return n;
}

}  // namespace rayfarm
