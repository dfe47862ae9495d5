// Replay vs a real throttled farm; see validation.h.
#include "replay/validation.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <sstream>
#include <stdexcept>
#include <thread>

#include "broker/broker.h"
#include "broker/local_farm.h"
#include "tracer/error.h"
#include "tracer/elapsed.h"
#include "tracer/nff_reader.h"
#include "tracer/render_job.h"
#include "tracer/renderer.h"

namespace rayfarm {
namespace {

constexpr double kReferenceWeight = 21.0;
constexpr double kFarmDeadlineS = 600;  // a validation job never hangs a test or a script

double weight_of(const ValidationSpec& spec, double throttle) {
  return spec.declare_speed ? kReferenceWeight / throttle : kReferenceWeight;
}

std::string worker_name(size_t i, double throttle) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "w%zu-x%g", i + 1, throttle);
  return buf;
}

// One single-threaded, throttled `rayfarm worker` process per throttle on the
// embedded local farm, all registered before the job starts.
nlohmann::json run_throttled_farm(const FarmJob& job, const ValidationSpec& spec) {
  LocalFarmOptions o;
  o.executable = spec.executable;
  o.threads = 1;
  o.weight = kReferenceWeight;
  o.credit = spec.credit;
  o.base_task_rows = spec.base_task_rows;
  o.policy = spec.policy;
  o.progress = false;
  o.log = [](const std::string&) {};
  o.deadline_s = kFarmDeadlineS;
  for (size_t i = 0; i < spec.throttles.size(); ++i) {
    const double t = spec.throttles[i];
    o.machines.push_back({worker_name(i, t), weight_of(spec, t), t});
  }
  return render_local_farm(job.scene_text, job.scene_name, job.settings, o).record;
}

// The replay's machines for the recorded workers, in registration order (the
// broker's tie-break for "longest idle"). Speed 1/throttle: the costs are
// full-speed seconds of this machine.
std::vector<SimMachine> machines_of(const nlohmann::json& record, double init_override) {
  std::vector<SimMachine> out;
  for (const nlohmann::json& w : record.at("workers")) {
    SimMachine m;
    m.name = w.at("name").get<std::string>();
    m.type = m.name;
    m.weight = w.at("weight").get<double>();
    m.speed = 1.0 / w.at("throttle").get<double>();
    m.credit = w.at("credit").get<int>();
    m.init_s = init_override >= 0 ? init_override : std::max(0.0, w.at("init_s").get<double>());
    out.push_back(m);
  }
  return out;
}

using Clock = std::chrono::steady_clock;

// The middle value (the mean of the middle two of an even count).
double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : (v[n / 2 - 1] + v[n / 2]) / 2;
}

// Seconds per row, one vector of rows per pass over the image.
using PassTimes = std::vector<std::vector<double>>;

// One throttled worker's share of measure_as_farm(): a pass over every row
// per entry of `times`, from row `first` on, resting (throttle - 1) x each
// row's time after it as the worker does after a task.
void time_rows_as_worker(const Renderer& renderer, int first, double throttle, PassTimes& times) {
  std::vector<float> rgb;
  for (std::vector<double>& pass : times) {
    const int h = static_cast<int>(pass.size());
    for (int i = 0; i < h; ++i) {
      const int y = (first + i) % h;
      const auto t0 = Clock::now();
      renderer.render_rows(y, y + 1, rgb);
      pass[static_cast<size_t>(y)] = seconds_since(t0);
      std::this_thread::sleep_for(std::chrono::duration<double>((throttle - 1) * pass[static_cast<size_t>(y)]));
    }
  }
}

// Row costs measured the way the throttled farm renders them. The farm's rows
// took 1.15x (median; 0.97-1.40x over 12 bench-validate runs, 2026-12-02) the
// time of the same rows timed alone, back to back: in the farm a worker rests
// between tasks, so each task starts on a cold core, and three workers share
// two cores. So one thread per worker, each with its own Renderer, times every
// row as that worker would, starting at its own offset; a row's cost is the
// median of its times, with enough passes that each row has at least
// `spec.repeats`.
RowCosts measure_as_farm(const Scene& scene, const RenderSettings& settings, const ValidationSpec& spec) {
  const int n = static_cast<int>(spec.throttles.size()), h = settings.height;
  const int passes = std::max(1, (spec.repeats + n - 1) / n);
  const PassTimes one_worker(static_cast<size_t>(passes), std::vector<double>(static_cast<size_t>(h)));
  std::vector<PassTimes> times(static_cast<size_t>(n), one_worker);
  std::vector<double> init_s(static_cast<size_t>(n));
  std::vector<std::thread> threads;
  for (int w = 0; w < n; ++w) {
    threads.emplace_back([&, w] {
      const auto t0 = Clock::now();
      const Renderer renderer(scene, settings);
      init_s[static_cast<size_t>(w)] = seconds_since(t0);
      time_rows_as_worker(renderer, w * h / n, spec.throttles[static_cast<size_t>(w)], times[static_cast<size_t>(w)]);
    });
  }
  for (std::thread& t : threads) t.join();
  RowCosts c;
  c.scene = spec.scene_path;
  c.source = "tracer, timed as the throttled farm renders";
  c.width = settings.width;
  c.spp = settings.spp;
  c.primitives = scene.primitive_count();
  c.init_s = *std::min_element(init_s.begin(), init_s.end());
  for (int y = 0; y < h; ++y) {
    std::vector<double> row;
    for (const auto& worker : times)
      for (const std::vector<double>& pass : worker) row.push_back(pass[static_cast<size_t>(y)]);
    c.rows.push_back(median(row));
  }
  return c;
}

const nlohmann::json& worker_entry(const nlohmann::json& record, const std::string& name) {
  for (const nlohmann::json& w : record.at("workers"))
    if (w.at("name") == name) return w;
  throw std::runtime_error("validation farm: worker " + name + " is missing from the job record");
}

const MachineResult* find_machine(const SimResult& r, const std::string& name) {
  for (const MachineResult& m : r.machines)
    if (m.name == name) return &m;
  return nullptr;
}

std::string fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

std::string markdown(const ValidationSpec& spec, const ValidationResult& v) {
  std::ostringstream s;
  s << "Scene " << spec.scene_path << ", " << spec.width << "x" << spec.height << ", " << spec.spp << " spp; "
    << v.workers.size() << " workers (1 thread each), task size "
    << "policy " << policy_name(spec.policy) << (spec.declare_speed ? " (speeds declared)" : "") << ", base " << spec.base_task_rows << " row(s), credit "
    << spec.credit << ". Measured sequential row cost " << fmt("%.3f", v.measured.total()) << " s, recorded "
    << fmt("%.3f", v.recorded.total()) << " s.\n\n";
  s << "| time | real s | predicted s (measured costs) | ratio | replayed s (recorded costs) | ratio |\n"
       "|---|---|---|---|---|---|\n";
  s << "| render (first dispatch -> last result) | " << fmt("%.3f", v.real_render_s) << " | "
    << fmt("%.3f", v.predicted.render_s) << " | " << fmt("%.2f", v.predicted.render_s / v.real_render_s) << " | "
    << fmt("%.3f", v.replayed.render_s) << " | " << fmt("%.2f", v.replayed.render_s / v.real_render_s) << " |\n";
  s << "| total (announce -> last result) | " << fmt("%.3f", v.real_total_s) << " | "
    << fmt("%.3f", v.predicted.makespan_s) << " | " << fmt("%.2f", v.predicted.makespan_s / v.real_total_s) << " | "
    << fmt("%.3f", v.replayed.makespan_s) << " | " << fmt("%.2f", v.replayed.makespan_s / v.real_total_s) << " |\n\n";
  s << "| worker | throttle | weight | real rows | predicted rows | replayed rows | real busy s | predicted busy s |\n"
       "|---|---|---|---|---|---|---|---|\n";
  for (const WorkerComparison& w : v.workers)
    s << "| " << w.name << " | " << fmt("%g", w.throttle) << " | " << fmt("%.4g", w.weight) << " | " << w.real_rows
      << " (" << fmt("%.1f%%", 100 * w.real_share) << ") | " << w.predicted_rows << " ("
      << fmt("%.1f%%", 100 * w.predicted_share) << ") | " << w.replayed_rows << " ("
      << fmt("%.1f%%", 100 * w.replayed_share) << ") | " << fmt("%.3f", w.real_busy_s) << " | "
      << fmt("%.3f", w.predicted_busy_s) << " |\n";
  return s.str();
}

}  // namespace

ValidationResult run_validation(const ValidationSpec& spec) {
  if (spec.throttles.empty()) throw InputError("validation: needs at least one worker throttle");
  if (spec.executable.empty()) throw InputError("validation: needs the rayfarm executable for the workers");
  const std::string text = read_nff_text(spec.scene_path);
  const Scene scene = parse_nff(text, spec.scene_path);
  RenderOverrides o;
  o.width = spec.width;
  o.height = spec.height;
  o.spp = spec.spp;
  o.threads = 1;
  const RenderSettings settings = derive_settings(scene, o);

  ValidationResult v;
  v.measured = measure_as_farm(scene, settings, spec);
  v.record = run_throttled_farm(FarmJob{text, spec.scene_path, settings}, spec);
  v.recorded = row_costs_from_record(v.record, "job record");
  v.real_render_s = v.record.at("render_s").get<double>();
  v.real_total_s = v.record.at("total_s").get<double>();

  SimOptions sim;
  sim.reference_weight = kReferenceWeight;
  sim.base_task_rows = spec.base_task_rows;
  sim.policy = spec.policy;
  sim.latency_s = spec.latency_s;
  sim.sequential_init_s = v.measured.init_s;
  v.predicted = simulate(v.measured, machines_of(v.record, v.measured.init_s), sim);
  v.replayed = simulate(v.recorded, machines_of(v.record, -1), sim);

  const int height = settings.height;
  for (size_t i = 0; i < spec.throttles.size(); ++i) {  // in the order of spec.throttles
    const nlohmann::json& w = worker_entry(v.record, worker_name(i, spec.throttles[i]));
    WorkerComparison c;
    c.name = w.at("name").get<std::string>();
    c.throttle = w.at("throttle").get<double>();
    c.weight = w.at("weight").get<double>();
    c.real_rows = w.at("rows").get<int>();
    c.real_busy_s = w.at("busy_s").get<double>();
    if (const MachineResult* p = find_machine(v.predicted, c.name)) {
      c.predicted_rows = p->rows;
      c.predicted_busy_s = p->busy_s;
    }
    if (const MachineResult* p = find_machine(v.replayed, c.name)) c.replayed_rows = p->rows;
    c.real_share = double(c.real_rows) / height;
    c.predicted_share = double(c.predicted_rows) / height;
    c.replayed_share = double(c.replayed_rows) / height;
    v.workers.push_back(c);
  }
  v.markdown = markdown(spec, v);
  return v;
}

}  // namespace rayfarm
