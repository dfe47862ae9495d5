// Discrete-event replay of the broker's dispatch on a list of machines, driven
// by a per-row cost profile. The decisions are the broker's own: the replay
// calls broker/dispatch_policy.h on a broker/task_board.h, exactly as the
// broker does after each batch of messages, and only models the rest: the
// broker announces the job at t = 0; machine i is ready after its stagger, init
// (parse + BVH build) and two message latencies; a machine renders its queued
// tasks in order at cost / speed; results come back one latency later. A
// machine may fall silent at `lost_at` (its tasks are requeued once the broker
// notices, `loss_detect_s` later), and a backup copy beaten by another machine
// still costs its machine the time (shown as wasted).
#pragma once

#include <string>
#include <vector>

#include "broker/dispatch_policy.h"
#include "replay/lab.h"
#include "replay/row_costs.h"

namespace rayfarm {

struct SimOptions {
  PolicyKind policy = PolicyKind::adaptive;
  double reference_weight = 21.0;
  int base_task_rows = 1;
  bool prior_frame = false;  // adaptive: the previous frame had these very costs (a still scene)
  double latency_s = 0;      // one-way message latency, broker <-> machine
  double stagger_s = 0;      // machine i starts loading i * stagger_s after the announcement
  double sequential_init_s = 0;  // init of the sequential run on the reference machine
  double loss_detect_s = 3;      // heartbeat interval x liveness (1 s x 3)
  bool keep_tasks = false;       // fill SimResult::tasks (load-distribution plots)
  int min_span_pixels = PolicyOptions{}.min_span_pixels;  // adaptive: narrowest pixel span; 0 = whole rows only
};

struct MachineResult {
  std::string name, type;
  double weight = 0, speed = 0;
  int credit = 0, task_rows = 0, tasks = 0;
  double rows = 0;         // rows rendered; a span counts as its share of a row
  int spans = 0;           // accepted tasks that were pixel spans of a row
  int backups_won = 0, attempts_wasted = 0;
  double ready_at = 0;     // job_ready reached the broker
  double busy_s = 0;       // rendering seconds of accepted tasks
  double wasted_s = 0;     // rendering seconds of beaten or lost attempts
  double last_done = 0;    // its last accepted result reached the broker
};

struct SimTask {
  int y0 = 0, y1 = 0;
  int x0 = 0, x1 = 0;  // pixels of the row(s)
  int machine = 0;
  bool backup = false, accepted = false;
  double dispatched = 0, started = 0, finished = 0;  // finished = result at the broker
};

struct SimResult {
  double makespan_s = 0;    // announcement -> last accepted result at the broker
  double first_ready_s = 0; // announcement -> first job_ready
  double render_s = 0;      // first dispatch -> last result (the job record's render_s)
  double sequential_s = 0;  // sequential_init_s + total row cost (speed 1)
  double speedup = 0;       // sequential_s / makespan_s
  double normalized = 0;    // sum of machine speeds
  double efficiency = 0;    // speedup / normalized
  double work_s = 0;        // sum of busy_s * speed: must equal the total row cost
  double wasted_s = 0;      // sum of wasted_s * speed
  double lower_bound_s = 0; // makespan_lower_bound()
  double bound_ratio = 0;   // makespan_s / lower_bound_s
  int backups = 0, requeued = 0;
  int tasks_done = 0, spans_done = 0;  // accepted tasks, and how many of them were pixel spans
  std::vector<MachineResult> machines;
  std::vector<SimTask> tasks;  // only with keep_tasks
};

// Throws std::invalid_argument for an empty machine list or cost profile.
SimResult simulate(const RowCosts& costs, const std::vector<SimMachine>& machines, const SimOptions& options);

// No dispatch can beat this: every machine starts rendering when it could
// first receive a task (stagger + latency + init + two latencies), then the
// work is spread perfectly by speed (water-filling), and the last result needs
// one more latency. Machines lost mid-job are counted as never there.
double makespan_lower_bound(const RowCosts& costs, const std::vector<SimMachine>& machines, const SimOptions& options);

}  // namespace rayfarm
