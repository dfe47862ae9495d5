// Labs: a heterogeneous set of machines described in one file
// (configs/labs/paper-lab.json: the paper's 46 SSC, 17 ELC, 14 R3000, 3 R4000).
// `rayfarm worker --lab FILE` runs all of them as throttled workers in one
// process, and `rayfarm replay` simulates them (replay/lab.h); both read the
// file through load_lab, so the format has one definition.
#pragma once

#include <string>
#include <vector>

#include "worker/worker_config.h"

namespace rayfarm {

// A lab is a room of workstations, not a botnet: more machines than this in
// one file is a typo (and `rayfarm worker --lab` would run them all at once).
inline constexpr int kMaxLabMachines = 10000;

// One entry of "machines": `count` workstations of one kind.
struct LabMachineType {
  std::string name;     // "name" key, else the worker config's file stem, else "machine"
  int count = 1;
  WorkerConfig config;  // the entry's worker config file, with the entry's overrides
  // Replay-only model knobs; a real worker measures these itself.
  double speed = 0;    // render speed vs the cost profile; 0 = derived from weight or throttle
  double init_s = -1;  // parse + BVH build seconds; < 0 = derived
};

struct Lab {
  std::string path;  // the file it came from ("" if built in code)
  std::string description;
  double reference_weight = 21.0;  // weight of the reference machine (Sun SSC)
  std::vector<LabMachineType> types;

  int machine_count() const;
};

// Keys: "description", "reference_weight", "machines": [{"config" (a worker
// config, relative to the lab file) and/or "weight", "count", optional "name",
// "throttle", "credit", "speed", "init_s"}]. Throws InputError naming the key
// path, e.g. "lab.json: machines[2].cuont: unknown key". At most
// kMaxLabMachines machines in all.
Lab load_lab(const std::string& path);

// One WorkerConfig per workstation, named "<type>-NN" (sun-ssc-07).
std::vector<WorkerConfig> lab_workers(const Lab& lab);

}  // namespace rayfarm
