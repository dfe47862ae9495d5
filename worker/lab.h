// Labs: a heterogeneous set of machines described in one file
// (configs/labs/paper-lab.json: the paper's 46 SSC, 17 ELC, 14 R3000, 3 R4000).
// `rayfarm worker --lab FILE` runs all of them as workers in one process, each
// throttled to its machine's relative speed, to replay a lab on one computer.
#pragma once

#include <string>
#include <vector>

#include "worker/worker_config.h"

namespace rayfarm {

// One WorkerConfig per machine, named "<config file stem>-NN" (sun-ssc-07).
// Machine config paths are relative to the lab file. Throws InputError
// "path: machines[2].count: ..." for bad entries.
std::vector<WorkerConfig> load_lab(const std::string& path);

}  // namespace rayfarm
