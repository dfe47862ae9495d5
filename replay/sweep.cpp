// Speedup sweeps and the replay's output files; see sweep.h.
#include "replay/sweep.h"

#include <algorithm>
#include <cstdio>
#include <map>
#include <sstream>

namespace rayfarm {
namespace {

std::string fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

}  // namespace

std::vector<SweepPoint> sweep(const RowCosts& costs, const std::vector<SimMachine>& machines, const SimOptions& options,
                              const std::string& series, const std::function<void(int, int)>& progress) {
  std::vector<SweepPoint> out;
  const int total = static_cast<int>(machines.size());
  for (int n = 1; n <= total; ++n) {
    const std::vector<SimMachine> subset(machines.begin(), machines.begin() + n);
    SweepPoint p{series, n, simulate(costs, subset, options)};
    p.result.machines.clear();
    p.result.tasks.clear();
    out.push_back(std::move(p));
    if (progress) progress(n, total);
  }
  return out;
}

double init_speedup_bound(const SimOptions& options, const RowCosts& costs) {
  return options.sequential_init_s > 0 ? (options.sequential_init_s + costs.total()) / options.sequential_init_s : 0;
}

std::string sweep_csv(const std::string& scene, const std::vector<SweepPoint>& points, double init_bound) {
  std::ostringstream s;
  s << "scene,series,machines,normalized,makespan_s,first_ready_s,render_s,sequential_s,speedup,efficiency,init_bound,lower_bound_s,bound_ratio\n";
  for (const SweepPoint& p : points) {
    const SimResult& r = p.result;
    s << scene << ',' << p.series << ',' << p.machines << ',' << fmt("%.4f", r.normalized) << ','
      << fmt("%.6g", r.makespan_s) << ',' << fmt("%.6g", r.first_ready_s) << ',' << fmt("%.6g", r.render_s) << ','
      << fmt("%.6g", r.sequential_s) << ',' << fmt("%.4f", r.speedup) << ',' << fmt("%.4f", r.efficiency) << ','
      << fmt("%.4f", init_bound) << ',' << fmt("%.6g", r.lower_bound_s) << ',' << fmt("%.4f", r.bound_ratio) << '\n';
  }
  return s.str();
}

std::string machines_csv(const SimResult& result) {
  double total_rows = 0;
  for (const MachineResult& m : result.machines) total_rows += m.rows;
  std::ostringstream s;
  s << "name,type,weight,speed,task_rows,tasks,rows,row_share,busy_s,ready_at,last_done\n";
  for (const MachineResult& m : result.machines)
    s << m.name << ',' << m.type << ',' << fmt("%g", m.weight) << ',' << fmt("%.4f", m.speed) << ',' << m.task_rows
      << ',' << m.tasks << ',' << fmt("%g", m.rows) << ',' << fmt("%.4f", total_rows > 0 ? m.rows / total_rows : 0.0) << ','
      << fmt("%.6g", m.busy_s) << ',' << fmt("%.6g", m.ready_at) << ',' << fmt("%.6g", m.last_done) << '\n';
  return s.str();
}

std::string tasks_csv(const SimResult& result) {
  std::ostringstream s;
  s << "machine,name,y0,y1,x0,x1,backup,accepted,dispatched,started,finished\n";
  for (const SimTask& t : result.tasks)
    s << t.machine << ',' << result.machines[static_cast<size_t>(t.machine)].name << ',' << t.y0 << ',' << t.y1 << ','
      << t.x0 << ',' << t.x1 << ','
      << t.backup << ',' << t.accepted << ',' << fmt("%.6g", t.dispatched) << ',' << fmt("%.6g", t.started) << ','
      << fmt("%.6g", t.finished) << '\n';
  return s.str();
}

std::string report_markdown(const ReportInput& in) {
  const SimResult& w = *in.whole;
  const SimOptions& o = *in.options;
  std::ostringstream s;
  s << "# Replay: " << in.scene << " on " << in.lab << "\n\n";
  s << "- Row costs: " << in.costs_source << " (" << in.costs->height() << " rows, total "
    << fmt("%.6g", in.costs->total()) << " s on a speed-1 machine)\n";
  s << "- Model: policy " << policy_name(o.policy) << (o.prior_frame ? " (costs known from the previous frame)" : "")
    << ", base " << o.base_task_rows << " row(s); init " << fmt("%.4g", o.sequential_init_s) << " s on a speed-1 machine; latency "
    << fmt("%.4g", o.latency_s * 1e3) << " ms; stagger " << fmt("%.4g", o.stagger_s * 1e3) << " ms/machine";
  if (o.policy == PolicyKind::adaptive)
    s << (o.min_span_pixels > 0 ? "; tail rows cut into spans of >= " + std::to_string(o.min_span_pixels) + " px" : "; whole rows only");
  s << "\n";
  const double bound = init_speedup_bound(o, *in.costs);
  if (bound > 0) s << "- Init-time bound on speedup (sequential / init): " << fmt("%.1f", bound) << "\n";
  s << "\n## Whole lab: " << w.machines.size() << " machines, " << fmt("%.2f", w.normalized) << " normalised\n\n";
  s << "| makespan s | lower bound s | ratio | first ready s | render s | sequential s | speedup | efficiency | backups | tasks | spans |\n"
       "|---|---|---|---|---|---|---|---|---|---|---|\n";
  s << "| " << fmt("%.4g", w.makespan_s) << " | " << fmt("%.4g", w.lower_bound_s) << " | " << fmt("%.4f", w.bound_ratio)
    << " | " << fmt("%.4g", w.first_ready_s) << " | " << fmt("%.4g", w.render_s) << " | " << fmt("%.6g", w.sequential_s)
    << " | " << fmt("%.2f", w.speedup) << " | " << fmt("%.3f", w.efficiency) << " | " << w.backups << " | " << w.tasks_done
    << " | " << w.spans_done << " |\n\n";
  s << "Lower bound: every machine's init, then the work spread perfectly by speed; ratio = makespan / bound.\n\n";
  struct TypeTotals { int machines = 0, tasks = 0, credit = 0; double rows = 0, busy = 0, speed = 0; };
  std::vector<std::string> order;
  std::map<std::string, TypeTotals> types;
  double total_rows = 0;
  for (const MachineResult& m : w.machines) {
    if (!types.count(m.type)) order.push_back(m.type);
    TypeTotals& t = types[m.type];
    t.machines += 1; t.rows += m.rows; t.tasks += m.tasks; t.busy += m.busy_s; t.speed = m.speed; t.credit = m.credit;
    total_rows += m.rows;
  }
  s << "| machine type | count | speed | credit | rows | row share | tasks | mean busy s |\n|---|---|---|---|---|---|---|---|\n";
  for (const std::string& name : order) {
    const TypeTotals& t = types[name];
    s << "| " << name << " | " << t.machines << " | " << fmt("%.3f", t.speed) << " | " << t.credit << " | " << fmt("%g", t.rows) << " | "
      << fmt("%.1f%%", 100.0 * t.rows / std::max(1.0, total_rows)) << " | " << t.tasks << " | "
      << fmt("%.4g", t.busy / t.machines) << " |\n";
  }
  if (in.points && !in.points->empty()) {
    s << "\n## Sweep\n\n| series | machines | normalised | makespan s | speedup | efficiency |\n|---|---|---|---|---|---|\n";
    const std::vector<SweepPoint>& pts = *in.points;
    for (size_t i = 0; i < pts.size(); ++i) {
      const SweepPoint& p = pts[i];
      const bool last_of_series = i + 1 == pts.size() || pts[i + 1].series != p.series;
      if (p.machines != 1 && p.machines % 10 != 0 && !last_of_series) continue;
      s << "| " << p.series << " | " << p.machines << " | " << fmt("%.2f", p.result.normalized) << " | "
        << fmt("%.4g", p.result.makespan_s) << " | " << fmt("%.2f", p.result.speedup) << " | "
        << fmt("%.3f", p.result.efficiency) << " |\n";
    }
  }
  return s.str();
}

}  // namespace rayfarm
