// Replay tests: the dispatch simulation on hand-made costs whose answer is
// known exactly, lab and cost-file parsing with their errors, row costs
// measured by the tracer, and a real throttled farm whose per-worker row
// shares the replay must reproduce (shares only: wall-clock times on a shared
// machine are reported by `rayfarm replay --validate`, never asserted).
#include <doctest/doctest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>

#include "replay/lab.h"
#include "replay/row_costs.h"
#include "replay/simulator.h"
#include "replay/sweep.h"
#include "replay/validation.h"
#include "tests/test_paths.h"
#include "tracer/error.h"
#include "tracer/nff_reader.h"

using namespace rayfarm;

namespace {

RowCosts uniform_rows(int rows, double seconds) {
  RowCosts c;
  c.scene = "uniform";
  c.source = "synthetic";
  c.rows.assign(static_cast<size_t>(rows), seconds);
  return c;
}

RowCosts random_rows(int rows, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> cost(0.01, 2.0);
  RowCosts c = uniform_rows(rows, 0);
  for (double& r : c.rows) r = cost(rng);
  return c;
}

std::vector<SimMachine> identical(int n, double speed = 1, int credit = 2, double init_s = 0) {
  std::vector<SimMachine> out;
  for (int i = 0; i < n; ++i) {
    SimMachine m;
    m.name = "m" + std::to_string(i);
    m.type = "m";
    m.speed = speed;
    m.credit = credit;
    m.init_s = init_s;
    out.push_back(m);
  }
  return out;
}

int total_rows(const SimResult& r) {
  int n = 0;
  for (const MachineResult& m : r.machines) n += m.rows;
  return n;
}

std::string temp_path(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() / "rayfarm-replay-test";
  std::filesystem::create_directories(dir);
  return (dir / name).string();
}

void write_file(const std::string& path, const std::string& text) {
  std::ofstream out(path);
  REQUIRE(out);
  out << text;
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST_CASE("replay: one machine takes the sequential time, init and latencies included") {
  const RowCosts costs = random_rows(50, 1);
  SimOptions o;
  o.sequential_init_s = 3;
  const SimResult r = simulate(costs, identical(1, 1, 2, 3), o);
  CHECK(r.makespan_s == doctest::Approx(3 + costs.total()).epsilon(1e-12));
  CHECK(r.speedup == doctest::Approx(1.0).epsilon(1e-12));
  CHECK(total_rows(r) == 50);

  // Credit 1 pays the round trip per task; credit 2 hides it behind the queued task.
  o.latency_s = 0.1;
  const RowCosts flat = uniform_rows(10, 1.0);
  const double ready = 3 + 2 * 0.1;
  CHECK(simulate(flat, identical(1, 1, 1, 3), o).makespan_s == doctest::Approx(ready + 10 * (1.0 + 0.2)));
  CHECK(simulate(flat, identical(1, 1, 2, 3), o).makespan_s == doctest::Approx(ready + 0.1 + 10 * 1.0 + 0.1));
}

TEST_CASE("replay: N identical machines on uniform rows take 1/N of the time") {
  const RowCosts costs = uniform_rows(64, 0.5);
  for (int n : {1, 2, 4, 8, 16, 64}) {
    const SimResult r = simulate(costs, identical(n), SimOptions{});
    CAPTURE(n);
    CHECK(r.makespan_s == doctest::Approx(costs.total() / n).epsilon(1e-12));
    CHECK(r.speedup == doctest::Approx(n).epsilon(1e-12));
    CHECK(r.efficiency == doctest::Approx(1.0).epsilon(1e-12));
    for (const MachineResult& m : r.machines) CHECK(m.rows == 64 / n);
  }
  // The first N tasks go to N different machines (the paper's static start).
  SimOptions keep;
  keep.keep_tasks = true;
  const SimResult r = simulate(costs, identical(8, 1, 2), keep);
  for (int i = 0; i < 8; ++i) CHECK(r.tasks[static_cast<size_t>(i)].machine == i);
}

TEST_CASE("replay: a constant init time caps speedup at sequential / init (Amdahl)") {
  const RowCosts costs = uniform_rows(512, 1765.82 / 512);  // Tetra-like: 25 s init, 1765.82 s sequential
  SimOptions o;
  o.sequential_init_s = 25;
  const double bound = init_speedup_bound(o, costs);
  CHECK(bound == doctest::Approx((25 + 1765.82) / 25));
  double previous = 0;
  for (int n : {1, 10, 46, 128, 512}) {
    const SimResult r = simulate(costs, identical(n, 1, 2, 25), o);
    CAPTURE(n);
    CHECK(r.speedup < bound);
    CHECK(r.speedup > previous);
    CHECK(r.first_ready_s == doctest::Approx(25));
    previous = r.speedup;
  }
  // 512 machines, one row each: init + one row, nothing left to share.
  CHECK(simulate(costs, identical(512, 1, 2, 25), o).makespan_s == doctest::Approx(25 + 1765.82 / 512));
}

TEST_CASE("replay: weighted task sizes follow the broker's task_rows_for") {
  std::vector<SimMachine> ms = identical(3);
  ms[0].weight = 17.9;  // ELC: round(17.9 / 21 * 4) = 3 rows
  ms[1].weight = 21.0;  // SSC: 4 rows
  ms[2].weight = 60.3;  // R4000: round(11.49) = 11 rows
  SimOptions o;
  o.base_task_rows = 4;
  o.weighted = true;
  o.keep_tasks = true;
  const SimResult r = simulate(uniform_rows(100, 0.1), ms, o);
  CHECK(r.machines[0].task_rows == 3);
  CHECK(r.machines[1].task_rows == 4);
  CHECK(r.machines[2].task_rows == 11);
  for (const SimTask& t : r.tasks)
    if (t.y1 != 100) CHECK(t.y1 - t.y0 == r.machines[static_cast<size_t>(t.machine)].task_rows);
  o.weighted = false;  // constant size: everybody gets the base
  for (const MachineResult& m : simulate(uniform_rows(100, 0.1), ms, o).machines) CHECK(m.task_rows == 4);
  // A tiny weight still gets one row.
  ms[0].weight = 0.1;
  o.weighted = true;
  CHECK(simulate(uniform_rows(10, 0.1), ms, o).machines[0].task_rows == 1);
}

TEST_CASE("replay: the simulated work equals the sum of row costs; faster machines get more rows") {
  const RowCosts costs = random_rows(400, 7);
  std::vector<SimMachine> ms = identical(2);
  ms[0].speed = 1;
  ms[1].speed = 3;
  SimOptions o;
  o.latency_s = 1e-3;
  const SimResult r = simulate(costs, ms, o);
  CHECK(r.work_s == doctest::Approx(costs.total()).epsilon(1e-9));
  CHECK(total_rows(r) == 400);
  CHECK(r.normalized == doctest::Approx(4));
  CHECK(double(r.machines[1].rows) / 400 == doctest::Approx(0.75).epsilon(0.05));
  // Whatever the mix, every row is rendered once and the work is conserved.
  std::mt19937 rng(3);
  for (int trial = 0; trial < 20; ++trial) {
    std::vector<SimMachine> mix = identical(1 + trial);
    for (SimMachine& m : mix) {
      m.speed = std::uniform_real_distribution<double>(0.2, 5)(rng);
      m.credit = 1 + trial % 3;
      m.init_s = std::uniform_real_distribution<double>(0, 3)(rng);
    }
    const SimResult t = simulate(costs, mix, o);
    CHECK(total_rows(t) == 400);
    CHECK(t.work_s == doctest::Approx(costs.total()).epsilon(1e-9));
  }
}

TEST_CASE("replay: row cost profiles resample, scale and round-trip through a file") {
  const RowCosts costs = random_rows(100, 11);
  const RowCosts up = resample_rows(costs, 512);
  CHECK(up.height() == 512);
  CHECK(up.total() == doctest::Approx(costs.total()).epsilon(1e-12));
  CHECK(resample_rows(costs, 7).total() == doctest::Approx(costs.total()).epsilon(1e-12));
  CHECK(resample_rows(uniform_rows(4, 1.0), 2).rows == std::vector<double>{2.0, 2.0});
  CHECK(scale_to_total(costs, 1765.82).total() == doctest::Approx(1765.82));

  const std::string path = temp_path("costs.json");
  write_file(path, row_costs_json(up).dump());
  const RowCosts back = load_row_costs(path);
  CHECK(back.rows == up.rows);
  CHECK(back.source == up.source);

  write_file(path, R"({"format": "rayfarm-row-costs/1", "rows": [1, 2], "scne": "x"})");
  CHECK(error_of([&] { load_row_costs(path); }).find("scne: unknown key") != std::string::npos);
  write_file(path, R"({"format": "rayfarm-row-costs/1", "rows": [1, -2]})");
  CHECK(error_of([&] { load_row_costs(path); }).find("rows[1]") != std::string::npos);
  CHECK(error_of([&] { load_row_costs(temp_path("missing.json")); }).find("cannot open") != std::string::npos);
}

TEST_CASE("replay: the paper lab loads with 80 machines, 85 normalised SSCs, in the paper's order") {
  const Lab lab = load_lab(test::source_dir() + "/configs/labs/paper-lab.json");
  CHECK(lab.machine_count() == 80);
  CHECK(lab.reference_weight == 21.0);
  const std::vector<SimMachine> ms = expand_lab(lab, LabModel{SpeedFrom::weight, 25});
  REQUIRE(ms.size() == 80);
  CHECK(normalized_count(ms) == doctest::Approx(85).epsilon(0.01));  // paper: "85 (approx)"
  CHECK(ms.front().type == "sun-ssc");
  CHECK(ms.back().type == "sgi-indigo-r4000");
  CHECK(ms.back().init_s == doctest::Approx(25 / (60.3 / 21)));
  CHECK(reference_machines(ms, 21.0).size() == 46);
  // Throttles describe the same speeds relative to the R4000.
  const std::vector<SimMachine> emu = expand_lab(lab, LabModel{SpeedFrom::throttle, 0});
  CHECK(emu.front().speed / emu.back().speed == doctest::Approx(21.0 / 60.3).epsilon(0.01));
}

TEST_CASE("replay: lab file errors name the key path and the file") {
  const std::string workers = test::source_dir() + "/configs/workers/";
  const std::string path = temp_path("lab.json");
  write_file(path, R"({"machines": [{"config": ")" + workers + R"(sun-ssc.json", "count": 2},
                                    {"weight": 60.3, "cuont": 3}]})");
  std::string e = error_of([&] { load_lab(path); });
  CHECK(e.find(path) != std::string::npos);
  CHECK(e.find("machines[1].count: missing") != std::string::npos);
  write_file(path, R"({"machines": [{"weight": 60.3, "count": 3, "cuont": 3}]})");
  CHECK(error_of([&] { load_lab(path); }).find("machines[0].cuont: unknown key") != std::string::npos);
  write_file(path, R"({"machines": [{"config": "nope.json", "count": 1}]})");
  e = error_of([&] { load_lab(path); });
  CHECK(e.find("machines[0].config") != std::string::npos);
  CHECK(e.find("nope.json") != std::string::npos);
  write_file(path, R"({"reference_wieght": 21, "machines": [{"weight": 1, "count": 1}]})");
  CHECK(error_of([&] { load_lab(path); }).find("reference_wieght: unknown key") != std::string::npos);
  CHECK(error_of([&] { load_lab(temp_path("no-lab.json")); }).find("cannot open") != std::string::npos);
}

TEST_CASE("replay: row costs measured with the tracer cover every row") {
  const Scene scene = read_nff_file(test::source_dir() + "/scenes/balls.nff");
  RenderSettings s;
  s.width = s.height = 24;
  s.spp = 1;
  s.threads = 1;
  int calls = 0;
  const RowCosts c = measure_row_costs(scene, s, "balls", 1, [&](int done, int total) {
    ++calls;
    CHECK(total == 24);
    CHECK(done == calls);
  });
  CHECK(c.height() == 24);
  CHECK(c.primitives == scene.primitive_count());
  for (double r : c.rows) CHECK(r > 0);
  CHECK(c.init_s > 0);
}

TEST_CASE("replay: a real throttled farm gives each worker the row share the replay predicts") {
  // Throttles 1, 2, 3: ideal shares 6/11, 3/11, 2/11 of the rows.
  ValidationSpec spec;
  spec.scene_path = test::source_dir() + "/scenes/balls.nff";
  spec.width = spec.height = 96;
  spec.spp = 64;
  spec.repeats = 1;
  spec.executable = test::rayfarm_exe();
  const ValidationResult v = run_validation(spec);

  REQUIRE(v.workers.size() == 3);
  CHECK(v.recorded.height() == 96);
  CHECK(v.predicted.work_s == doctest::Approx(v.measured.total()).epsilon(1e-9));
  CHECK(v.replayed.work_s == doctest::Approx(v.recorded.total()).epsilon(1e-9));
  const double ideal[] = {6.0 / 11, 3.0 / 11, 2.0 / 11};
  int rows = 0;
  for (size_t i = 0; i < 3; ++i) {
    const WorkerComparison& w = v.workers[i];
    CAPTURE(w.name);
    CHECK(w.throttle == doctest::Approx(static_cast<double>(i + 1)));
    // Generous: a shared 2-core machine slows workers unevenly.
    CHECK(std::abs(w.real_share - w.predicted_share) < 0.12);
    CHECK(std::abs(w.predicted_share - ideal[i]) < 0.08);
    rows += w.real_rows;
  }
  CHECK(rows == 96);
  CHECK(v.workers[0].real_rows > v.workers[2].real_rows);
  CHECK(v.markdown.find("| w1-x1 |") != std::string::npos);
}
