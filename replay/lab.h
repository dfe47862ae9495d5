// Lab: the machines a replay runs on. A lab file (configs/labs/*.json) lists
// machine types by worker config (configs/workers/*.json: weight, credit) and
// count, in the order the machines join; the replay expands it into one
// SimMachine per workstation. How fast a machine renders relative to the row
// cost profile comes from its SPECfp92-like weight (the paper's normalisation)
// or, for a throttled local farm, from its throttle.
#pragma once

#include <string>
#include <vector>

#include "worker/lab.h"

namespace rayfarm {

// Where a machine's render speed comes from when the lab does not say.
enum class SpeedFrom {
  weight,    // weight / reference_weight: costs are reference-machine seconds (paper)
  throttle,  // 1 / throttle: costs are seconds of this machine at full speed (local farm)
};

// Model knobs that belong to the replay, not to the machines.
struct LabModel {
  SpeedFrom speed_from = SpeedFrom::weight;
  double init_s = 0;  // init on a machine of speed 1; a machine of speed s takes init_s / s
};

// One workstation of an expanded lab.
struct SimMachine {
  std::string name;  // "sun-ssc-7"
  std::string type;  // "sun-ssc"
  double weight = 21.0;
  double speed = 1.0;
  int credit = 2;
  double init_s = 0;
  double lost_at = -1;  // falls silent at this time (replay only); < 0 = never
};

// All machines, in lab order (type by type), with speed and init resolved.
std::vector<SimMachine> expand_lab(const Lab& lab, const LabModel& model);

// Machines of the reference weight only (the paper's homogeneous SSC runs).
std::vector<SimMachine> reference_machines(const std::vector<SimMachine>& machines, double reference_weight);

// Sum of speeds: the paper's "number of machines normalised to the SSC".
double normalized_count(const std::vector<SimMachine>& machines);

}  // namespace rayfarm
