// Discrete-event replay of the broker's dispatch policy (protocol/SPEC.md,
// "Dispatch") on a list of machines, driven by a per-row cost profile. The
// broker announces the job at t = 0; machine i is ready after its stagger,
// init (parse + BVH build) and two message latencies; it then gets up to
// `credit` tasks, longest-idle machine first, one task per machine per pass;
// afterwards each returned result frees a credit for the next task. Tasks are
// cut coarse to fine at round(weight / reference * base) rows (the broker's own
// task_rows_for and RowCursor). A machine renders its queue in order at cost / speed.
#pragma once

#include <string>
#include <vector>

#include "replay/lab.h"
#include "replay/row_costs.h"

namespace rayfarm {

struct SimOptions {
  double reference_weight = 21.0;
  int base_task_rows = 1;
  bool weighted = false;   // false: every machine gets base_task_rows (the paper's constant size)
  double latency_s = 0;    // one-way message latency, broker <-> machine
  double stagger_s = 0;    // machine i starts loading i * stagger_s after the announcement
  double sequential_init_s = 0;  // init of the sequential run on the reference machine
  bool keep_tasks = false;       // fill SimResult::tasks (load-distribution plots)
};

struct MachineResult {
  std::string name, type;
  double weight = 0, speed = 0;
  int credit = 0, task_rows = 0, tasks = 0, rows = 0;
  double ready_at = 0;     // job_ready reached the broker
  double busy_s = 0;       // rendering seconds on this machine
  double last_done = 0;    // its last result reached the broker
};

struct SimTask {
  int y0 = 0, y1 = 0;
  int machine = 0;
  double dispatched = 0, started = 0, finished = 0;  // finished = result at the broker
};

struct SimResult {
  double makespan_s = 0;    // announcement -> last result at the broker
  double first_ready_s = 0; // announcement -> first job_ready
  double render_s = 0;      // first dispatch -> last result (the job record's render_s)
  double sequential_s = 0;  // sequential_init_s + total row cost (speed 1)
  double speedup = 0;       // sequential_s / makespan_s
  double normalized = 0;    // sum of machine speeds
  double efficiency = 0;    // speedup / normalized
  double work_s = 0;        // sum of busy_s * speed: must equal the total row cost
  std::vector<MachineResult> machines;
  std::vector<SimTask> tasks;  // only with keep_tasks
};

// Throws std::invalid_argument for an empty machine list or cost profile.
SimResult simulate(const RowCosts& costs, const std::vector<SimMachine>& machines, const SimOptions& options);

}  // namespace rayfarm
