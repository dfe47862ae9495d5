// Replay tests: the dispatch simulation on hand-made costs whose answer is
// known exactly, lab and cost-file parsing with their errors, row costs
// measured by the tracer, and a real throttled farm whose per-worker row
// shares the replay must reproduce (shares only: wall-clock times on a shared
// machine are reported by `rayfarm replay --validate`, never asserted).
#include <doctest/doctest.h>

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <cstdlib>
#include <random>

#include "replay/lab.h"
#include "replay/paper_reference.h"
#include "replay/replay_job.h"
#include "replay/row_costs.h"
#include "replay/simulator.h"
#include "replay/sweep.h"
#include "replay/validation.h"
#include "tests/run_command.h"
#include "tests/test_files.h"
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
  // Per process: several build trees may run their tests at once.
  return (test::process_dir("replay-test") / name).string();
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
  o.policy = PolicyKind::weighted;  // constant one-row tasks, with credit
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

TEST_CASE("replay: a staggered start delays late machines, which then get less work") {
  SimOptions o;
  o.policy = PolicyKind::paper;
  o.stagger_s = 10;  // machine i starts loading at 10 i seconds
  const SimResult r = simulate(uniform_rows(4, 1.0), identical(2, 1, 1), o);
  CHECK(r.makespan_s == doctest::Approx(4));  // machine 0 is done before machine 1 is ready
  CHECK(r.machines[1].rows == 0);
  const SimResult long_job = simulate(uniform_rows(40, 1.0), identical(2, 1, 1), o);
  CHECK(long_job.makespan_s == doctest::Approx(25));  // 10 rows alone, then 30 rows shared
  CHECK(long_job.machines[1].ready_at == doctest::Approx(10));
}

TEST_CASE("replay: weighted task sizes follow the broker's task_rows_for") {
  std::vector<SimMachine> ms = identical(3);
  ms[0].weight = 17.9;  // ELC: round(17.9 / 21 * 4) = 3 rows
  ms[1].weight = 21.0;  // SSC: 4 rows
  ms[2].weight = 60.3;  // R4000: round(11.49) = 11 rows
  SimOptions o;
  o.base_task_rows = 4;
  o.policy = PolicyKind::weighted;
  o.keep_tasks = true;
  const SimResult r = simulate(uniform_rows(100, 0.1), ms, o);
  CHECK(r.machines[0].task_rows == 3);
  CHECK(r.machines[1].task_rows == 4);
  CHECK(r.machines[2].task_rows == 11);
  // Mixed sizes: a task is its machine's size or cut short where another's band begins.
  int full = 0, rows = 0;
  for (const SimTask& t : r.tasks) {
    CHECK(t.y1 - t.y0 <= r.machines[static_cast<size_t>(t.machine)].task_rows);
    full += t.y1 - t.y0 == r.machines[static_cast<size_t>(t.machine)].task_rows;
    rows += t.y1 - t.y0;
  }
  CHECK(rows == 100);
  CHECK(full * 2 > static_cast<int>(r.tasks.size()));
  o.policy = PolicyKind::paper;  // constant size: everybody gets the base
  for (const MachineResult& m : simulate(uniform_rows(100, 0.1), ms, o).machines) CHECK(m.task_rows == 4);
  // A tiny weight still gets one row.
  ms[0].weight = 0.1;
  o.policy = PolicyKind::weighted;
  CHECK(simulate(uniform_rows(10, 0.1), ms, o).machines[0].task_rows == 1);
}

TEST_CASE("replay: the simulated work equals the sum of row costs, faster machines get more rows") {
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

TEST_CASE("replay: row costs from a job record share each task's render time among its rows") {
  nlohmann::json record = {{"scene", "s.nff"},
                           {"settings", {{"width", 8}, {"height", 4}, {"spp", 1}}},
                           {"workers", {{{"name", "a"}, {"init_s", 0.5}}, {{"name", "b"}, {"init_s", 0.25}}}},
                           {"tasks", {{{"y0", 0}, {"y1", 3}, {"render_s", 0.3}}, {{"y0", 3}, {"y1", 4}, {"render_s", 1.0}}}}};
  const RowCosts c = row_costs_from_record(record, "rec.json");
  REQUIRE(c.height() == 4);
  for (int y = 0; y < 3; ++y) CHECK(c.rows[static_cast<size_t>(y)] == doctest::Approx(0.1));
  CHECK(c.rows[3] == 1.0);
  CHECK(c.init_s == 0.25);
  CHECK(c.scene == "s.nff");
  record["tasks"].erase(1);
  CHECK(error_of([&] { row_costs_from_record(record, "rec.json"); }).find("row 3 is in no task") != std::string::npos);
  record["tasks"].push_back({{"y0", 2}, {"y1", 4}, {"render_s", 1.0}});
  CHECK(error_of([&] { row_costs_from_record(record, "rec.json"); }).find("rec.json: tasks[1].y0: row 2 is in two tasks") !=
        std::string::npos);
}

TEST_CASE("replay: rayfarm replay writes the report, per-machine and sweep files for the paper lab") {
  const std::string costs = temp_path("cli-costs.json");
  RowCosts c = random_rows(64, 5);
  c.scene = "synthetic";
  write_file(costs, row_costs_json(c).dump());
  const std::string out = temp_path("cli-out");
  std::filesystem::remove_all(out);
  const std::string cmd = test::rayfarm_exe() + " replay --costs " + costs + " --lab " + test::source_dir() +
                          "/configs/labs/paper-lab.json --init-s 0.5 --sweep --no-plots -o " + out + " >/dev/null 2>&1";
  REQUIRE(std::system(cmd.c_str()) == 0);
  std::ifstream sweep(out + "/sweep.csv");
  REQUIRE(sweep);
  int homogeneous = 0, heterogeneous = 0;
  for (std::string line; std::getline(sweep, line);) {
    homogeneous += line.find(",homogeneous,") != std::string::npos;
    heterogeneous += line.find(",heterogeneous,") != std::string::npos;
  }
  CHECK(homogeneous == 46);
  CHECK(heterogeneous == 80);
  CHECK(std::filesystem::exists(out + "/replay.md"));
  CHECK(std::filesystem::exists(out + "/machines.csv"));
  CHECK(load_row_costs(out + "/costs.json").rows == c.rows);
  const std::string bad = test::rayfarm_exe() + " replay --costs " + costs + " --lab " + temp_path("none.json") +
                          " >/dev/null 2>&1";
  CHECK(std::system(bad.c_str()) != 0);
}

TEST_CASE("replay: a number option given NaN or infinity is refused, naming the option") {
  // NaN passes a `value < min || value > max` check, and a NaN latency, stagger
  // or init made events that never come due: the replay ran forever. `timeout`
  // turns such a hang into a failure here.
  const std::string replay = "timeout 60 " + test::rayfarm_exe() + " replay --costs " + test::source_dir() +
                             "/scenes/costs/tetra.json --lab " + test::source_dir() + "/configs/labs/paper-lab.json ";
  for (const char* option : {"--latency-ms", "--stagger-ms", "--init-s", "--sequential-s"}) {
    for (const char* value : {"nan", "inf", "-1"}) {
      CAPTURE(option);
      CAPTURE(value);
      const test::CommandResult r = test::run_command(replay + option + " " + value);
      CHECK(r.exit_code != 0);
      CHECK(r.exit_code != 124);  // timeout's: it hung
      // The bound is 1e9 s, written in the option's unit.
      const std::string bound = std::string(option).find("-ms") != std::string::npos ? "1e+12" : "1e+09";
      CHECK(r.output.find(std::string(option) + ": expected a finite number in [0, " + bound + "], found " + value) !=
            std::string::npos);
    }
  }
  const test::CommandResult r = test::run_command(replay + "--throttles 1,nan");
  CHECK(r.exit_code != 0);
  CHECK(r.output.find("--throttles: expected a finite number in [1, 1000], found nan") != std::string::npos);
}

TEST_CASE("replay: a time option past 1e9 s is refused, naming the option and the value") {
  // 1e300 s of init left 0 s of rendering in the report, and a sweep overflowed to inf.
  const std::string replay = "timeout 60 " + test::rayfarm_exe() + " replay --costs " + test::source_dir() +
                             "/scenes/costs/tetra.json --lab " + test::source_dir() + "/configs/labs/paper-lab.json ";
  const struct {
    const char *option, *value, *range;
  } cases[] = {{"--init-s", "1e300", "in [0, 1e+09]"},
               {"--sequential-s", "1.7e308", "in [0, 1e+09]"},
               {"--latency-ms", "1e300", "in [0, 1e+12]"},
               {"--stagger-ms", "2e12", "in [0, 1e+12]"}};
  for (const auto& c : cases) {
    CAPTURE(c.option);
    const test::CommandResult r = test::run_command(replay + c.option + " " + c.value);
    CHECK(r.exit_code != 0);
    CHECK(r.output.find(std::string(c.option) + ": expected a finite number " + c.range + ", found " + c.value) !=
          std::string::npos);
  }
  // The sequential time's bound says what was given, in few digits ("45.117188 s" before).
  const test::CommandResult r = test::run_command(replay + "--init-s 45.125 --sequential-s 10");
  CHECK(r.exit_code != 0);
  CHECK(r.output.find("--sequential-s 10 must exceed the init time, 45.125 s") != std::string::npos);
}

TEST_CASE("replay: a costs file of no work, or a row past 1e9 s, is refused naming the file") {
  const std::string path = temp_path("absurd-costs.json");
  // All zero: the replay printed a report with no numbers at all.
  write_file(path, R"({"format": "rayfarm-row-costs/1", "rows": [0, 0, 0]})");
  CHECK(error_of([&] { load_row_costs(path); }) ==
        path + ": rows: all 3 rows take 0 s (a profile needs some rendering time)");
  write_file(path, R"({"format": "rayfarm-row-costs/1", "rows": [1, 1e300, 1]})");
  CHECK(error_of([&] { load_row_costs(path); }).find(path + ": rows[1]: expected a finite number of seconds in [0, 1e+09]") ==
        0);
  // A job record whose tasks took no time is no profile either.
  write_file(path, R"({"settings": {"width": 2, "height": 1, "spp": 1}, "tasks": [{"y0": 0, "y1": 1, "render_s": 0}]})");
  CHECK(error_of([&] { load_row_costs(path); }).find(path + ": rows: all 1 rows take 0 s") == 0);
}

TEST_CASE("replay: a bad value in a costs file or job record is shown with the file and its place") {
  const std::string path = temp_path("bad-costs.json");
  const struct {
    std::string text, message;
  } cases[] = {
      {R"({"format": "rayfarm-row-costs/1", "rows": [1, -2]})", ": rows[1]: expected a finite number of seconds"},
      {R"({"format": "rayfarm-row-costs/1", "rows": [1, -2]})", ", found -2"},
      {R"({"format": "rayfarm-row-costs/1", "rows": [1, "3.5"]})", ": rows[1]: expected a finite number of seconds"},
      {R"({"format": "rayfarm-row-costs/1", "rows": [1, "3.5"]})", ", found \"3.5\""},
      {R"({"settings": {"width": 2, "height": 0, "spp": 1}, "tasks": []})",
       ": settings.height: expected an integer in [1, 65536], found 0"},
      {R"({"settings": {"width": 2, "height": 1, "spp": 1}, "tasks": [{"y0": 0, "y1": 1, "render_s": null}]})",
       ": tasks[0].render_s: expected a finite number of seconds in [0, 1e+09], found null"},
      {R"({"settings": {"width": 2, "height": 2, "spp": 1}, "tasks": [{"y0": 0, "y1": 5, "render_s": 1}]})",
       ": tasks[0].y1: expected an integer in [1, 2], found 5"},
  };
  for (const auto& c : cases) {
    CAPTURE(c.text);
    write_file(path, c.text);
    const std::string e = error_of([&] { load_row_costs(path); });
    CHECK(e.find(path + ":") == 0);
    CHECK(e.find(c.message) != std::string::npos);
  }
}

TEST_CASE("replay: --costs naming a device or a pipe of endless data is refused, not read forever") {
  // /dev/zero was read at 2 GB a second until memory ran out. Here 80 MB of
  // zeros through a pipe, so that a regression ends (as invalid JSON) instead
  // of taking the machine's memory; `ulimit -v` would not do, as a sanitizer
  // build reserves terabytes of address space.
  const test::CommandResult r = test::run_command("head -c 80000000 /dev/zero | timeout 60 " + test::rayfarm_exe() +
                                                  " replay --costs /dev/stdin --lab " + test::source_dir() +
                                                  "/configs/labs/paper-lab.json");
  CHECK(r.exit_code != 0);
  CHECK(r.exit_code != 124);  // timeout's: it hung
  CHECK(r.output.find("/dev/stdin: larger than the") != std::string::npos);
}

TEST_CASE("replay: an output folder that cannot be written fails before rows are measured or a farm runs") {
  const std::filesystem::path dir = test::scratch_dir("replay-unwritable");
  const std::string file = test::write_file(dir / "a-file", "not a folder\n");
  const std::string scene = test::write_file(dir / "tiny.nff", test::tiny_scene());
  const std::string lab = " --lab " + test::source_dir() + "/configs/labs/paper-lab.json";
  for (const std::string& mode : {lab, std::string(" --validate")}) {
    CAPTURE(mode);
    const test::CommandResult r = test::run_command(test::rayfarm_exe() + " replay --scene " + scene + mode +
                                                    " --repeats 1 --no-plots -o " + file + "/out");
    CHECK(r.exit_code != 0);
    CHECK(r.output.find(file + "/out: cannot create folder") != std::string::npos);
    CHECK(r.output.find("measuring rows") == std::string::npos);
    CHECK(r.output.find("validating") == std::string::npos);
  }
}

TEST_CASE("replay: an option of the lab model with --validate, or of --validate without it, is refused") {
  const std::filesystem::path dir = test::scratch_dir("replay-modes");
  const std::string scene = test::write_file(dir / "tiny.nff", test::tiny_scene());
  const std::string lab = test::source_dir() + "/configs/labs/paper-lab.json";
  const std::string replay = test::rayfarm_exe() + " replay ";
  const struct {
    std::string args, message;
  } cases[] = {
      {"--validate --scene " + scene + " --lab " + lab, "--lab does not apply to --validate"},
      {"--validate --scene " + scene + " --sweep", "--sweep does not apply to --validate"},
      {"--validate --scene " + scene + " --stagger-ms 600", "--stagger-ms does not apply to --validate"},
      {"--costs " + test::source_dir() + "/scenes/costs/tetra.json --lab " + lab + " --declare-speed",
       "--declare-speed applies only with --validate"},
      {"--costs " + test::source_dir() + "/scenes/costs/tetra.json --lab " + lab + " --throttles 1,2",
       "--throttles applies only with --validate"},
  };
  for (const auto& c : cases) {
    CAPTURE(c.args);
    const test::CommandResult r = test::run_command(replay + c.args);
    CHECK(r.exit_code != 0);
    CHECK(r.output.find(c.message) != std::string::npos);
    CHECK(r.output.find("validating") == std::string::npos);
  }
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

TEST_CASE("replay: row costs measured with the tracer cover every row, once per pass") {
  const Scene scene = read_nff_file(test::source_dir() + "/scenes/balls.nff");
  RenderSettings s;
  s.width = s.height = 24;
  s.spp = 1;
  s.threads = 1;
  int calls = 0;
  const RowCosts c = measure_row_costs(scene, s, "balls", 2, [&](int done, int total) {
    ++calls;
    CHECK(total == 2 * 24);  // two passes over the image, not each row twice in a row
    CHECK(done == calls);
  });
  CHECK(calls == 2 * 24);
  CHECK(c.height() == 24);
  CHECK(c.primitives == scene.primitive_count());
  for (double r : c.rows) CHECK(r > 0);
  CHECK(c.init_s > 0);
}

TEST_CASE("replay: a real throttled farm gives each worker the row share the replay predicts") {
  // Two single-thread workers, throttles 1 and 3: ideal shares 3/4 and 1/4 (a
  // dispatch that ignored speed would give 1/2 each). Two workers keep the
  // 2-core machine from being oversubscribed by the farm itself.
  ValidationSpec spec;
  spec.scene_path = test::source_dir() + "/scenes/balls.nff";
  spec.width = spec.height = 128;
  spec.spp = 100;
  spec.repeats = 1;
  spec.throttles = {1, 3};
  spec.policy = PolicyKind::weighted;  // in order: the shares follow from speeds alone
  spec.executable = test::rayfarm_exe();
  const ValidationResult v = run_validation(spec);

  REQUIRE(v.workers.size() == 2);
  // Every row timed the way the farm renders it (one thread per worker).
  REQUIRE(v.measured.height() == 128);
  for (double r : v.measured.rows) CHECK(r > 0);
  CHECK(v.recorded.height() == 128);
  CHECK(v.predicted.work_s == doctest::Approx(v.measured.total()).epsilon(1e-9));
  CHECK(v.replayed.work_s == doctest::Approx(v.recorded.total()).epsilon(1e-9));
  const double ideal[] = {0.75, 0.25};
  for (size_t i = 0; i < 2; ++i) {
    const WorkerComparison& w = v.workers[i];
    CAPTURE(w.name);
    CHECK(w.throttle == spec.throttles[i]);
    CHECK(std::abs(w.predicted_share - ideal[i]) < 0.08);
    // Generous (seen: up to 0.09): other work on a shared machine slows the
    // workers unevenly. Equal shares would still be 0.25 off.
    CHECK(std::abs(w.real_share - w.predicted_share) < 0.15);
  }
  CHECK(v.workers[0].real_rows + v.workers[1].real_rows == 128);
  CHECK(v.markdown.find("| w2-x3 |") != std::string::npos);
}

TEST_CASE("replay: the lower bound is init plus the work spread by speed, and no policy beats it") {
  const RowCosts costs = random_rows(200, 11);
  SimOptions o;
  o.latency_s = 0.01;
  // One machine: its start (init + three latencies), all the work, one latency back.
  const std::vector<SimMachine> one = identical(1, 2, 1, 3);
  CHECK(makespan_lower_bound(costs, one, o) == doctest::Approx(3 + 0.03 + costs.total() / 2 + 0.01));
  // A machine ready only after the others would have finished adds nothing.
  std::vector<SimMachine> two = identical(2, 1, 1, 0);
  two[1].init_s = 1e6;
  CHECK(makespan_lower_bound(costs, two, o) == doctest::Approx(0.03 + costs.total() + 0.01));
  std::mt19937 rng(5);
  for (PolicyKind policy : {PolicyKind::paper, PolicyKind::weighted, PolicyKind::adaptive}) {
    o.policy = policy;
    std::vector<SimMachine> mix = identical(7);
    for (SimMachine& m : mix) {
      m.speed = std::uniform_real_distribution<double>(0.3, 3)(rng);
      m.weight = 21 * m.speed;
      m.init_s = std::uniform_real_distribution<double>(0, 5)(rng);
    }
    const SimResult r = simulate(costs, mix, o);
    CAPTURE(policy_name(policy));
    CHECK(r.lower_bound_s == doctest::Approx(makespan_lower_bound(costs, mix, o)));
    CHECK(r.bound_ratio >= 1.0);
    CHECK(r.makespan_s == doctest::Approx(r.bound_ratio * r.lower_bound_s));
  }
}

TEST_CASE("replay: a machine lost mid-job has its tasks requeued, every row is still done once") {
  const RowCosts costs = uniform_rows(60, 1.0);
  std::vector<SimMachine> ms = identical(3, 1, 2);
  ms[1].lost_at = 5;  // falls silent; the broker notices loss_detect_s later
  for (PolicyKind policy : {PolicyKind::paper, PolicyKind::adaptive}) {
    SimOptions o;
    o.policy = policy;
    const SimResult r = simulate(costs, ms, o);
    CAPTURE(policy_name(policy));
    CHECK(r.requeued >= 1);
    CHECK(total_rows(r) == 60);
    CHECK(r.machines[1].rows <= 5);  // only what it returned before t = 5
    CHECK(r.work_s == doctest::Approx(costs.total()));
    CHECK(r.makespan_s > 60.0 / 3);
  }
}

TEST_CASE("replay: backups keep a stalled machine from holding the job (default policy)") {
  const RowCosts costs = uniform_rows(40, 1.0);
  std::vector<SimMachine> ms = identical(2, 1, 2);
  ms[1].speed = 1e-6;  // heartbeats, but its tasks would take a million times as long
  SimOptions o;
  const SimResult alone = simulate(costs, identical(1, 1, 2), o);
  const SimResult r = simulate(costs, ms, o);
  CHECK(r.backups >= 1);
  CHECK(r.machines[1].rows == 0);
  CHECK(r.makespan_s < 1.5 * alone.makespan_s);
  o.policy = PolicyKind::paper;  // no backups: the job waits for the stalled machine
  CHECK(simulate(costs, ms, o).makespan_s > 1e5);
}

// The goal of the default policy on the paper's whole lab (docs/replay.md):
// within 3% of the lower bound on every paper scene, from the committed
// profiles. The pixel spans of the tail rows are what gets it there: in whole
// rows the same policy is 7-9% above the bound on Mount, Rings and Gears.
TEST_CASE("replay: the default policy is within 3% of the lower bound on the paper's whole lab, with spans") {
  double worst_rows = 0;
  for (const char* scene : {"tetra", "balls", "mount", "rings", "gears"}) {
    ReplayJob job;
    job.costs_path = test::source_dir() + "/scenes/costs/" + scene + ".json";
    job.paper = scene;
    job.lab_path = test::source_dir() + "/configs/labs/paper-lab.json";
    job.sim.latency_s = 0.005;
    const ReplayOutput spans = run_replay(job);
    CAPTURE(scene);
    CHECK(spans.whole.bound_ratio <= 1.03);
    CHECK(spans.whole.spans_done > 0);
    CHECK(spans.whole.work_s == doctest::Approx(spans.costs.total()));  // every pixel once
    job.sim.min_span_pixels = 0;
    const ReplayOutput rows = run_replay(job);
    CHECK(rows.whole.spans_done == 0);
    worst_rows = std::max(worst_rows, rows.whole.bound_ratio);
  }
  CHECK(worst_rows > 1.05);
}

TEST_CASE("replay: with the paper's start-up the paper policy is within 10% of every speedup the paper reports") {
  // The paper's policy on its labs: 46 SSCs (Fig. 3) and all 80 machines (Fig. 4).
  const std::string ssc46 = temp_path("ssc-46.json");
  write_file(ssc46, R"({"reference_weight": 21.0, "machines": [{"config": ")" + test::source_dir() +
                        R"(/configs/workers/sun-ssc.json", "count": 46}]})");
  struct Reported {
    const char* scene;
    std::string lab;
    double speedup;
  };
  const std::string whole = test::source_dir() + "/configs/labs/paper-lab.json";
  const Reported reported[] = {{"tetra", ssc46, 22.91}, {"balls", ssc46, 42.06}, {"mount", ssc46, 36.56},
                               {"balls", whole, 64.19}, {"mount", whole, 52.72}};
  for (const Reported& r : reported) {
    ReplayJob job;
    job.costs_path = test::source_dir() + "/scenes/costs/" + r.scene + ".json";
    job.paper = r.scene;
    job.lab_path = r.lab;
    job.sim.policy = PolicyKind::paper;
    job.sim.latency_s = 0.005;
    const ReplayOutput staggered = run_replay(job);
    CAPTURE(r.scene);
    CAPTURE(r.lab);
    CHECK(staggered.options.stagger_s == doctest::Approx(kPaperServerStaggerS));
    CHECK(std::abs(staggered.whole.speedup / r.speedup - 1) < 0.10);
    if (std::string(r.scene) == "tetra") {  // without the start-up, Tetra's init-bound run is 21% off
      job.stagger_s = 0.0;
      const ReplayOutput plain = run_replay(job);
      CHECK(plain.options.stagger_s == 0);
      CHECK(plain.whole.speedup / r.speedup - 1 > 0.15);
    }
  }
}

TEST_CASE("replay: a --plot-script that does not exist is refused before the replay runs") {
  const std::filesystem::path dir = test::scratch_dir("replay-plot-script");
  const std::string missing = (dir / "no-plot.py").string();
  const test::CommandResult r = test::run_command(
      test::rayfarm_exe() + " replay --costs " + test::source_dir() + "/scenes/costs/tetra.json --lab " +
      test::source_dir() + "/configs/labs/paper-lab.json --sweep -o " + (dir / "out").string() +
      " --plot-script " + missing);
  CHECK(r.exit_code != 0);
  CHECK(r.output.find("--plot-script") != std::string::npos);
  CHECK(r.output.find(missing) != std::string::npos);
  CHECK_FALSE(std::filesystem::exists(dir / "out" / "replay.md"));
}

TEST_CASE("replay: a size of the right shape but empty, and -o naming an input, name the option at fault") {
  const std::filesystem::path dir = test::scratch_dir("replay-option-at-fault");
  const std::string costs = test::write_file(dir / "costs.json", "{}");
  const std::string replay = test::rayfarm_exe() + " replay --no-plots --costs " + costs + " --lab " +
                             test::source_dir() + "/configs/labs/paper-lab.json ";
  const struct {
    std::string args, output;
  } cases[] = {
      // Was "--size: expected WxH (e.g. 128x128), found "0x0"", of a size of that shape.
      {"--size 0x0", "rayfarm: --size 0x0: width and height must be at least 1\n"},
      {"--size 0x4", "rayfarm: --size 0x4: width and height must be at least 1\n"},
      // Was "--costs FILE: cannot create folder (Not a directory)", of the option that was right.
      {"-o " + costs, "rayfarm: -o " + costs + " is the same file as --costs\n"},
  };
  for (const auto& c : cases) {
    CAPTURE(c.args);
    const test::CommandResult r = test::run_command(replay + c.args);
    CHECK(r.exit_code == 1);
    CHECK(r.output == c.output);
  }
}

TEST_CASE("replay: a measurement spp or size the renderer refuses is reported naming --spp and --size") {
  const std::filesystem::path dir = test::scratch_dir("replay-measurement");
  const std::string scene = test::write_file(dir / "tiny.nff", test::tiny_scene());
  const std::string replay = test::rayfarm_exe() + " replay --no-plots --scene " + scene + " --lab " +
                             test::source_dir() + "/configs/labs/paper-lab.json --repeats 1 ";
  const struct {
    std::string args, message;
  } cases[] = {
      {"--spp 3", "rayfarm: --spp: expected a perfect square k*k (1, 4, 9, 16, 25, ...), found 3"},
      {"--spp 0 --size 8x8", "rayfarm: --spp: expected a value in [1, 65536], found 0"},
      {"--size 100000x8", "replay: --size 100000x8 / --spp 1: width must be between 1 and 65536, found 100000"},
  };
  for (const auto& c : cases) {
    CAPTURE(c.args);
    const test::CommandResult r = test::run_command(replay + c.args);
    CHECK(r.exit_code != 0);
    CHECK(r.output.find(c.message) != std::string::npos);
  }
}

TEST_CASE("replay: a --size that is no WxH of whole numbers is refused as given") {
  const std::string replay = test::rayfarm_exe() + " replay --no-plots --scene missing.nff --lab " +
                             test::source_dir() + "/configs/labs/paper-lab.json --size ";
  // A side past int's range was read as another number (1215752191 here).
  for (const char* size : {"99999999999x2", "4x 4", "+4x4", "4x4x", "4x", "x4", "4*4"}) {
    CAPTURE(size);
    const test::CommandResult r = test::run_command(replay + "'" + size + "'");
    CHECK(r.exit_code != 0);
    CHECK(r.output.find(std::string("--size: expected WxH (e.g. 128x128), found \"") + size + "\"") !=
          std::string::npos);
  }
}

TEST_CASE("replay: an output the disk will not take is named with the reason") {
  // Past a file-size limit, as on a full disk: "cannot write" alone left the
  // cause to guess (text files of the service's state folder are written alike).
  const std::filesystem::path dir = test::scratch_dir("replay-file-too-large");
  const test::CommandResult r = test::run_command(
      "trap '' XFSZ; ulimit -f 2; " + test::rayfarm_exe() + " replay --costs " + test::source_dir() +
      "/scenes/costs/tetra.json --lab " + test::source_dir() + "/configs/labs/paper-lab.json --no-plots -o " +
      (dir / "out").string());
  CHECK(r.exit_code != 0);
  CHECK(r.output.find((dir / "out").string() + "/costs.json: cannot write (File too large)") != std::string::npos);
}

TEST_CASE("replay: --costs inside the -o folder is refused, not overwritten by the rescaled profile") {
  const std::filesystem::path dir = test::scratch_dir("replay-costs-in-output");
  const std::string costs = (dir / "costs.json").string();
  std::filesystem::copy_file(test::source_dir() + "/scenes/costs/tetra.json", costs);
  const std::string before = test::file_bytes(costs);
  const test::CommandResult r =
      test::run_command(test::rayfarm_exe() + " replay --no-plots --costs " + costs + " --lab " +
                        test::source_dir() + "/configs/labs/paper-lab.json --rows 64 -o " + dir.string());
  CHECK(r.exit_code != 0);
  CHECK(r.output.find("-o " + costs + " is the same file as --costs") != std::string::npos);
  CHECK(test::file_bytes(costs) == before);
}
