// Speedup curves: the replay run on growing subsets of a lab, as the paper adds
// machines (Fig. 3: 1..46 SSCs; Fig. 4: all 80 workstations in the order SSC,
// ELC, R3000, R4000), plus the CSV and Markdown files `rayfarm replay` writes.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "replay/simulator.h"

namespace rayfarm {

struct SweepPoint {
  std::string series;  // "homogeneous" or "heterogeneous"
  int machines = 0;
  SimResult result;    // per-machine results dropped to keep sweeps small
};

// simulate() on machines[0..n) for n = 1..machines.size(); `progress(n, total)`.
std::vector<SweepPoint> sweep(const RowCosts& costs, const std::vector<SimMachine>& machines, const SimOptions& options,
                              const std::string& series, const std::function<void(int, int)>& progress = {});

// Upper bound on speedup from the constant init time (paper section 4.3:
// sequential / init, e.g. 1765.82 / 25 = 70.6 for Tetra); 0 when there is no init.
double init_speedup_bound(const SimOptions& options, const RowCosts& costs);

// scene,series,machines,normalized,makespan_s,first_ready_s,render_s,sequential_s,speedup,efficiency,init_bound,
// lower_bound_s,bound_ratio
std::string sweep_csv(const std::string& scene, const std::vector<SweepPoint>& points, double init_bound);

// name,type,weight,speed,task_rows,tasks,rows,row_share,busy_s,ready_at,last_done
std::string machines_csv(const SimResult& result);

// machine,name,y0,y1,backup,accepted,dispatched,started,finished (SimResult::tasks)
std::string tasks_csv(const SimResult& result);

// A short Markdown report: settings, the whole-lab result, per-type totals and
// the sweep at a few sizes.
struct ReportInput {
  std::string scene, costs_source, lab;
  const RowCosts* costs = nullptr;
  const SimOptions* options = nullptr;
  const SimResult* whole = nullptr;
  const std::vector<SweepPoint>* points = nullptr;  // may be empty
};
std::string report_markdown(const ReportInput& in);

}  // namespace rayfarm
