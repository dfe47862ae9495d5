// The `rayfarm replay` pipeline; see replay_job.h.
#include "replay/replay_job.h"

#include <cstdio>
#include <filesystem>

#include "tracer/text_file.h"
#include "replay/paper_reference.h"
#include "tracer/error.h"
#include "tracer/nff_reader.h"
#include "tracer/render_job.h"

namespace rayfarm {
namespace {

namespace fs = std::filesystem;

// The renderer's complaint ("spp must be ...") named no option; these are the
// options that set what it complains about.
RenderSettings measurement_settings(const Scene& scene, const RenderOverrides& o) {
  try {
    return derive_settings(scene, o);
  } catch (const InputError& e) {
    std::string options = "--spp " + std::to_string(o.spp);
    if (o.width && o.height)
      options = "--size " + std::to_string(*o.width) + "x" + std::to_string(*o.height) + " / " + options;
    throw InputError("replay: " + options + ": " + e.what());
  }
}

RowCosts acquire_costs(const ReplayJob& job, const ReplayProgress& progress) {
  if (job.costs_path.empty() == job.scene_path.empty())
    throw InputError("replay: give exactly one of --costs FILE or --scene FILE");
  if (!job.costs_path.empty()) return load_row_costs(job.costs_path);
  const Scene scene = read_nff_file(job.scene_path);
  RenderOverrides o;
  o.width = job.width;
  o.height = job.height;
  o.spp = job.spp;
  o.threads = job.threads;
  const RenderSettings settings = measurement_settings(scene, o);
  const std::string name = fs::path(job.scene_path).stem().string();
  return measure_row_costs(scene, settings, name, job.repeats, [&](int done, int total) {
    if (progress) progress("measuring rows of " + name, done, total);
  });
}

// Resampling and scaling as asked (or as --paper implies). Returns the init
// time of a speed-1 machine.
double shape_costs(const ReplayJob& job, RowCosts& costs, std::string& scene) {
  std::optional<int> rows = job.rows;
  std::optional<double> sequential = job.sequential_s;
  std::optional<double> init = job.init_s;
  if (!job.paper.empty()) {
    const auto p = paper_scene(job.paper);
    if (!p) throw InputError("--paper: unknown scene '" + job.paper + "' (tetra, balls, mount, rings, gears)");
    scene = p->name;
    if (!rows) rows = kPaperRows;
    if (!sequential) sequential = p->sequential_s;
    if (!init) init = paper_init_s(*p);
  }
  if (rows && *rows != costs.height()) costs = resample_rows(costs, *rows);
  const double init_s = init.value_or(costs.init_s);
  if (sequential) {
    if (*sequential <= init_s) {
      char text[128];
      std::snprintf(text, sizeof text, "--sequential-s %g must exceed the init time, %g s", *sequential, init_s);
      throw InputError(text);
    }
    costs = scale_to_total(costs, *sequential - init_s);
  }
  costs.init_s = init_s;
  return init_s;
}

// The whole lab's numbers, for scripts (make replay-paper).
nlohmann::json replay_json(const ReplayOutput& out) {
  const SimResult& w = out.whole;
  return {{"scene", out.scene},
          {"policy", policy_name(out.options.policy)},
          {"prior_frame", out.options.prior_frame},
          {"machines", w.machines.size()},
          {"normalized", w.normalized},
          {"makespan_s", w.makespan_s},
          {"lower_bound_s", w.lower_bound_s},
          {"stagger_s", out.options.stagger_s},
          {"bound_ratio", w.bound_ratio},
          {"tasks", w.tasks_done},
          {"spans", w.spans_done},
          {"sequential_s", w.sequential_s},
          {"speedup", w.speedup},
          {"efficiency", w.efficiency},
          {"backups", w.backups},
          {"wasted_s", w.wasted_s}};
}

void write_outputs(const ReplayJob& job, ReplayOutput& out) {
  const fs::path dir(job.out_dir);
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw InputError(job.out_dir + ": cannot create directory: " + ec.message());
  auto put = [&](const std::string& name, const std::string& text) {
    write_text_file((dir / name).string(), text);
    out.files.push_back((dir / name).string());
  };
  put("costs.json", row_costs_json(out.costs).dump(1) + "\n");
  put("replay.md", out.markdown);
  put("machines.csv", machines_csv(out.whole));
  put("replay.json", replay_json(out).dump(1) + "\n");
  put("tasks.csv", tasks_csv(out.whole));
  if (!out.points.empty()) put("sweep.csv", sweep_csv(out.scene, out.points, out.init_bound));
}

}  // namespace

ReplayOutput run_replay(const ReplayJob& job, const ReplayProgress& progress) {
  if (job.lab_path.empty()) throw InputError("replay: --lab FILE is required");
  ReplayOutput out;
  out.lab = load_lab(job.lab_path);  // before a possibly long measurement
  out.costs = acquire_costs(job, progress);
  out.scene = out.costs.scene;
  const double init_s = shape_costs(job, out.costs, out.scene);
  out.costs.scene = out.scene;

  SimOptions sim = job.sim;
  sim.stagger_s = job.stagger_s.value_or(job.paper.empty() ? 0.0 : kPaperServerStaggerS);
  sim.reference_weight = out.lab.reference_weight;
  sim.sequential_init_s = init_s;
  std::vector<SimMachine> machines = expand_lab(out.lab, LabModel{job.speed_from, init_s});
  if (job.credit)
    for (SimMachine& m : machines) m.credit = *job.credit;
  out.options = sim;
  SimOptions whole = sim;
  whole.keep_tasks = true;  // tasks.csv: the load distribution (the paper's Figures 2 and 5)
  out.whole = simulate(out.costs, machines, whole);
  out.init_bound = init_speedup_bound(sim, out.costs);

  if (job.sweep) {
    const auto report = [&](const char* what) {
      return [&progress, what](int done, int total) {
        if (progress) progress(what, done, total);
      };
    };
    const std::vector<SimMachine> homogeneous = reference_machines(machines, out.lab.reference_weight);
    if (!homogeneous.empty()) out.points = sweep(out.costs, homogeneous, sim, "homogeneous", report("sweep (reference machines)"));
    std::vector<SweepPoint> all = sweep(out.costs, machines, sim, "heterogeneous", report("sweep (all machines)"));
    out.points.insert(out.points.end(), all.begin(), all.end());
  }
  ReportInput in;
  in.scene = out.scene;
  in.costs_source = out.costs.source;
  in.lab = job.lab_path;
  in.costs = &out.costs;
  in.options = &sim;
  in.whole = &out.whole;
  in.points = &out.points;
  out.markdown = report_markdown(in);
  if (!job.out_dir.empty()) write_outputs(job, out);
  return out;
}

}  // namespace rayfarm
