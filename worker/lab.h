// Labs: a heterogeneous set of machines described in one file
// (configs/labs/paper-lab.json: the paper's 46 SSC, 17 ELC, 14 R3000, 3 R4000).
// `rayfarm worker --lab FILE` runs all of them as workers in one process, each
// throttled to its machine's relative speed, to replay a lab on one computer.
#pragma once

#include <string>
#include <vector>

#include "worker/worker_config.h"

namespace rayfarm {

// One WorkerConfig per machine, named "<config file stem or name>-NN"
// (sun-ssc-07). Entries: "config" (relative to the lab file) and/or "weight",
// "count", optional "name", "credit", "throttle"; the replay-only "speed" and
// "init_s" are accepted and ignored (replay/lab.h reads the same files).
// Throws InputError "path: machines[2].cuont: unknown key" for bad entries.
std::vector<WorkerConfig> load_lab_workers(const std::string& path);

}  // namespace rayfarm
