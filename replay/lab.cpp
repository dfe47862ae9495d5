// A lab expanded into simulated machines; see lab.h.
#include "replay/lab.h"

namespace rayfarm {

std::vector<SimMachine> expand_lab(const Lab& lab, const LabModel& model) {
  std::vector<SimMachine> out;
  for (const LabMachineType& t : lab.types) {
    SimMachine m;
    m.type = t.name;
    m.weight = t.config.weight;
    m.credit = t.config.credit;
    if (t.speed > 0)
      m.speed = t.speed;
    else
      m.speed = model.speed_from == SpeedFrom::weight ? t.config.weight / lab.reference_weight : 1.0 / t.config.throttle;
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
