// Farm tests: a real broker, real workers (processes or threads), real sockets
// on tcp://127.0.0.1 ephemeral ports, real kill -9. Every distributed image is
// compared byte for byte with an in-process render of the same scene. Small
// scenes (64x64, a few spp) and short heartbeats keep each case to seconds;
// every wait is bounded by a deadline so nothing can hang.
#include <doctest/doctest.h>

#include <signal.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <set>
#include <thread>

#include "broker/broker.h"
#include "broker/child_process.h"
#include "broker/local_farm.h"
#include "broker/task_board.h"
#include "protocol/transport.h"
#include "tests/farm_peers.h"
#include "tests/test_paths.h"
#include "tracer/nff_reader.h"
#include "tracer/renderer.h"
#include "worker/lab.h"
#include "worker/worker.h"
#include "worker/worker_config.h"

using namespace rayfarm;
using namespace rayfarm::protocol;
using namespace rayfarm::test;
using Clock = std::chrono::steady_clock;

namespace {

std::string read_text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  REQUIRE(in);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

}  // namespace

TEST_CASE("farm: task board cuts by worker size, requeues lost tasks first, keeps first result only") {
  TaskBoard board(10);
  const TaskRecord* a = board.next(1, "a", 3, 0.0);
  REQUIRE(a);
  CHECK(a->y0 == 0);
  CHECK(a->y1 == 3);
  const TaskRecord* b = board.next(2, "b", 1, 0.0);  // coarse to fine: row 8 is next after 0
  CHECK(b->y0 == 8);
  CHECK(b->y1 == 9);
  board.requeue(0, 1, 1.0);
  const TaskRecord* again = board.next(2, "b", 1, 1.0);  // requeued task keeps its rows
  CHECK(again->id == 0);
  CHECK(again->rows() == 3);
  CHECK(again->attempt() == 2);
  CHECK(board.accept(1, 0, 1, {0, 3, 0, 1}, 2.0, 0, 0) == Verdict::stale);
  CHECK(board.accept(1, 0, 2, {0, 3, 0, 1}, 2.0, 0, 0) == Verdict::unassigned);
  CHECK(board.accept(2, 0, 2, {0, 4, 0, 1}, 2.0, 0, 0) == Verdict::mismatch);
  CHECK(board.accept(2, 0, 2, {0, 3, 0, 1}, 2.0, 0, 0) == Verdict::accepted);
  CHECK(board.accept(2, 0, 2, {0, 3, 0, 1}, 2.0, 0, 0) == Verdict::duplicate);
  CHECK(board.accept(2, 99, 1, {0, 3, 0, 1}, 2.0, 0, 0) == Verdict::unassigned);
  CHECK(board.rows_done() == 3);
  const TaskRecord* rest = board.next(1, "a", 100, 3.0);
  CHECK(rest->y0 == 3);
  CHECK(rest->y1 == 8);  // cut short where row 8, handed out already, begins
  const TaskRecord* last = board.next(1, "a", 100, 3.0);
  CHECK(last->y0 == 9);
  CHECK(last->y1 == 10);  // cut short at the bottom of the image
  CHECK(board.next(1, "a", 1, 3.0) == nullptr);
}

TEST_CASE("farm: worker and broker configs load, unknown keys name their path") {
  const std::string dir = test::source_dir() + "/configs/";
  CHECK(load_worker_config(dir + "workers/sun-ssc.json").weight == 21.0);
  CHECK(load_worker_config(dir + "workers/sun-elc.json").weight == 17.9);
  CHECK(load_worker_config(dir + "workers/sgi-indigo-r3000.json").weight == 24.2);
  CHECK(load_worker_config(dir + "workers/sgi-indigo-r4000.json").weight == 60.3);
  load_worker_config(dir + "workers/modern.json");
  const BrokerConfig b = load_broker_config(dir + "broker.json");
  CHECK(b.reference_weight == 21.0);
  CHECK(b.policy == PolicyKind::adaptive);
  CHECK(task_rows_for(b, 60.3) == 0);  // adaptive: sized at each dispatch
  CHECK(weighted_task_rows(60.3, b.reference_weight, b.base_task_rows) == 3);  // the paper's R4000 = 2.87 SSCs
  CHECK(weighted_task_rows(17.9, b.reference_weight, b.base_task_rows) == 1);
  CHECK(policy_options(b).min_span_pixels == 16);  // the default: tail rows in spans of >= 16 px
  CHECK(policy_options(parse_broker_config(R"({"min_span_pixels": 0})", "b.json")).min_span_pixels == 0);
  CHECK_THROWS_WITH_AS(parse_broker_config(R"({"min_span_pixels": -1})", "b.json"),
                       doctest::Contains("b.json: min_span_pixels: expected an integer in [0, 65536]"), InputError);

  const std::string path = "/tmp/rayfarm-farm-test-config-" + std::to_string(getpid()) + ".json";
  auto error_for = [&](const std::string& text) -> std::string {
    std::ofstream(path) << text;
    try {
      load_worker_config(path);
    } catch (const InputError& e) {
      return e.what();
    }
    return "";
  };
  CHECK(error_for(R"({"heartbeat": {"intervl_ms": 100}})") == path + ": heartbeat.intervl_ms: unknown key");
  CHECK(error_for(R"({"weigth": 3})") == path + ": weigth: unknown key");
  CHECK(error_for(R"({"credit": 0})").find("credit: expected an integer in [1, 64]") != std::string::npos);
  CHECK(error_for(R"({"name": )").find("invalid JSON") != std::string::npos);
  CHECK(error_for(R"({"max_isa": "avx3"})").find("max_isa: max_isa must be one of sse2, sse4.2") != std::string::npos);
  std::ofstream(path) << R"({"machines": [{"config": "workers/sun-ssc.json", "cuont": 2}]})";
  try {
    lab_workers(load_lab(path));
    FAIL("a lab entry with a misspelt key loaded");
  } catch (const InputError& e) {
    CHECK(std::string(e.what()).find("machines[0].") != std::string::npos);
  }
  std::remove(path.c_str());

  // The paper's lab: 46 SSC, 17 ELC, 14 R3000, 3 R4000 = 80 machines, ~85 SSCs.
  const std::vector<WorkerConfig> lab = lab_workers(load_lab(dir + "labs/paper-lab.json"));
  REQUIRE(lab.size() == 80);
  std::map<double, int> by_weight;
  double normalised = 0;
  for (const WorkerConfig& c : lab) {
    ++by_weight[c.weight];
    normalised += c.weight / 21.0;
    CHECK(c.throttle * c.weight == doctest::Approx(60.3).epsilon(0.001));  // speed ~ weight; the R4000 runs unthrottled
  }
  CHECK(by_weight == std::map<double, int>{{17.9, 17}, {21.0, 46}, {24.2, 14}, {60.3, 3}});
  CHECK(normalised == doctest::Approx(85).epsilon(0.01));
  CHECK(lab.front().name == "sun-ssc-01");
}

TEST_CASE("farm: config text loaders report overflow and bad keys with the source name") {
  // Found by fuzzing (fuzz/broker_config, fuzz/lab): 1e999 escaped the loaders
  // as an uncaught nlohmann::out_of_range, naming neither file nor place.
  CHECK_THROWS_WITH_AS(parse_worker_config(R"({"weight": 1e999})", "w.json"),
                       "w.json: invalid JSON: number out of range at line 1, column 12: 1e999 does not fit a double",
                       InputError);
  CHECK_THROWS_WITH_AS(parse_broker_config(R"({"liveness":1e999})", "broker.json"),
                       "broker.json: invalid JSON: number out of range at line 1, column 13: 1e999 does not fit a double",
                       InputError);
  const WorkerConfigLoader no_files = [](const std::string& p) -> WorkerConfig {
    throw InputError(p + ": cannot open (no files here)");
  };
  CHECK_THROWS_WITH_AS(parse_lab(R"({"machines": [{"weight": 1e999, "count": 1}]})", "labs/l.json", no_files),
                       "labs/l.json: invalid JSON: number out of range at line 1, column 26: 1e999 does not fit a double",
                       InputError);
  // The text loaders are the file loaders' rules: same keys, same errors.
  CHECK(parse_worker_config(R"({"weight": 60.3, "heartbeat": {"liveness": 4}})", "w.json").liveness == 4);
  CHECK(parse_broker_config(R"({"base_task_rows": 4})", "b.json").base_task_rows == 4);
  CHECK_THROWS_WITH_AS(parse_worker_config(R"({"weigth": 3})", "w.json"), "w.json: weigth: unknown key", InputError);
  CHECK_THROWS_WITH_AS(parse_lab(R"({"machines": [{"config": "w.json", "count": 1}]})", "labs/l.json", no_files),
                       doctest::Contains("machines[0].config: labs/w.json: cannot open (no files here)"), InputError);
}

TEST_CASE("farm: three workers of different weights render the in-process image, task sizes follow weights") {
  const FarmJob job = small_job(64, 64, 4);
  BrokerConfig cfg = test_broker_config(3);
  cfg.base_task_rows = 4;  // ELC 17.9 -> 3 rows, SSC 21.0 -> 4, R4000 60.3 -> 11
  cfg.policy = PolicyKind::weighted;
  LogCapture log;
  Broker broker(cfg, log.sink());
  const std::string dir = test::source_dir() + "/configs/workers/";
  std::vector<ChildProcess> workers;
  workers.push_back(spawn_worker(broker.endpoint(), "elc", {"--config", dir + "sun-elc.json"}));
  workers.push_back(spawn_worker(broker.endpoint(), "ssc", {"--config", dir + "sun-ssc.json"}));
  workers.push_back(spawn_worker(broker.endpoint(), "r4000", {"--config", dir + "sgi-indigo-r4000.json"}));
  const FarmResult r = broker.run(job, deadline(60));
  broker.shutdown_workers();

  CHECK(identical(r.rgb, in_process(job)));
  const std::map<std::string, int> expected_rows = {{"elc", 3}, {"ssc", 4}, {"r4000", 11}};
  for (const auto& [name, rows] : expected_rows) CHECK(worker_entry(r.record, name)["task_rows"] == rows);
  int rows_total = 0;
  for (const auto& t : r.record["tasks"]) {
    rows_total += t["rows"].get<int>();
    // A task is its worker's size, or cut short where a band of another size
    // (or the bottom of the image) begins (broker/row_order.h). How many are
    // cut depends on the order in which the three workers ask.
    CHECK(t["rows"] <= expected_rows.at(t["worker"]));
    CHECK(t["attempts"].size() == 1);
  }
  // The job's first task (the record lists tasks as cut) comes from an
  // untouched frame: band 0, whole, whichever worker asked first.
  const auto& first = r.record["tasks"].front();
  CHECK(first["y0"] == 0);
  CHECK(first["rows"] == expected_rows.at(first["worker"]));
  CHECK(rows_total == 64);
  CHECK(r.record["rays"]["eye"] == 64 * 64 * 4);
  for (auto& w : workers) CHECK(w.wait_for(5));
}

TEST_CASE("farm: a job whose tail rows are cut into pixel spans renders the in-process image byte for byte") {
  const FarmJob job = small_job(64, 32, 4);
  BrokerConfig cfg = test_broker_config(3);
  cfg.min_span_pixels = 4;  // narrow spans, so a small image has several per row
  LogCapture log;
  Broker broker(cfg, log.sink());
  std::vector<std::unique_ptr<ThreadWorker>> workers;
  for (const char* name : {"a", "b", "c"})
    workers.push_back(std::make_unique<ThreadWorker>(thread_worker_config(broker.endpoint(), name)));
  // What a journal hears: every handed-out task, and only whole rows accepted.
  int spans_sent = 0;
  std::vector<float> journaled(static_cast<size_t>(64) * 32 * 3, -1.0f);
  std::vector<int> journaled_times(32, 0);
  uint64_t journaled_eye = 0;
  FarmHooks hooks;
  hooks.sent = [&](const PixelBand& t) { spans_sent += t.x0 > 0 || t.x1 < 64; };
  hooks.accepted = [&](const TaskResult& row) {
    CHECK(row.x0 == 0);
    CHECK(row.x1 == 64);
    REQUIRE(row.rgb.size() == static_cast<size_t>(row.y1 - row.y0) * 64 * 3);
    std::copy(row.rgb.begin(), row.rgb.end(), journaled.begin() + static_cast<ptrdiff_t>(row.y0) * 64 * 3);
    for (int y = row.y0; y < row.y1; ++y) journaled_times[static_cast<size_t>(y)] += 1;
    journaled_eye += row.stats.eye;
  };
  const FarmResult r = broker.run(job, deadline(60), hooks);
  workers.clear();

  CHECK(identical(r.rgb, in_process(job)));
  // The journal got every row once, whole, with the rays of all its spans.
  CHECK(identical(journaled, r.rgb));
  for (int n : journaled_times) CHECK(n == 1);
  CHECK(journaled_eye == 64 * 32 * 4);
  CHECK(r.record["rays"]["eye"] == 64 * 32 * 4);  // every pixel's rays counted once
  // Every pixel is in exactly one task; spans are one row, left to right.
  std::vector<int> pixels(32, 0);
  int spans = 0, whole_rows = 0;
  for (const auto& t : r.record["tasks"]) {
    const int y0 = t["y0"], y1 = t["y1"], x0 = t["x0"], x1 = t["x1"];
    if (x0 == 0 && x1 == 64) {
      whole_rows += y1 - y0;
    } else {
      ++spans;
      CHECK(y1 - y0 == 1);
      CHECK(x1 - x0 >= 4);
      CHECK(pixels[static_cast<size_t>(y0)] == x0);
    }
    for (int y = y0; y < y1; ++y) pixels[static_cast<size_t>(y)] += x1 - x0;
  }
  for (int px : pixels) CHECK(px == 64);
  // The tail was cut, not the start: the first wave (a row per worker) and a
  // good share of the rest went out whole. (How many rows are cut depends on
  // the measured costs: tests/dispatch_policy_test.cpp pins it on fixed ones.)
  CHECK(spans > 0);
  CHECK(spans_sent >= spans);
  CHECK(whole_rows >= 32 / 4);
  for (size_t i = 0; i < 3; ++i) CHECK(r.record["tasks"][i]["x1"].get<int>() - r.record["tasks"][i]["x0"].get<int>() == 64);
  int worker_rows = 0, worker_spans = 0;
  for (const auto& w : r.record["workers"]) worker_rows += w["rows"].get<int>(), worker_spans += w["spans"].get<int>();
  CHECK(worker_rows == 32);
  CHECK(worker_spans == spans);
}

TEST_CASE("farm: workers at SSE4.2, AVX2 and native SIMD width each render the in-process image byte for byte") {
  // A mixed lab: one worker capped at SSE4.2 whose libm also runs without
  // FMA (glibc's own switch, as on a pre-Haswell CPU), one capped at AVX2 by
  // its config file, one at this CPU's widest kernels. Each renders the whole
  // of mount (triangles, glass spheres, shadows) alone on its own farm, so
  // every row of the image is compared for every width, whatever the timing.
  const FarmJob job{read_text(test::source_dir() + "/scenes/mount.nff"), "mount.nff", small_settings(64, 64, 4)};
  const std::vector<float> expected = in_process(job);
  const std::string config = "/tmp/rayfarm-farm-test-avx2-" + std::to_string(getpid()) + ".json";
  std::ofstream(config) << R"({"max_isa": "avx2"})";
  auto sse42 = [](const std::string& endpoint) {
    return ChildProcess("/usr/bin/env", {"GLIBC_TUNABLES=glibc.cpu.hwcaps=-AVX2,-FMA", test::rayfarm_exe(), "worker",
                                         "--connect", endpoint, "--name", "sse42", "--threads", "1", "--heartbeat-ms",
                                         "100", "--liveness", "5", "--quiet", "--max-isa", "sse4.2"});
  };
  auto avx2 = [&](const std::string& endpoint) { return spawn_worker(endpoint, "avx2", {"--config", config}); };
  auto native = [](const std::string& endpoint) { return spawn_worker(endpoint, "native"); };
  const std::vector<std::pair<const char*, std::function<ChildProcess(const std::string&)>>> widths = {
      {"sse42", sse42}, {"avx2", avx2}, {"native", native}};
  for (const auto& [name, spawn] : widths) {
    CAPTURE(name);
    BrokerConfig cfg = test_broker_config(1);
    cfg.base_task_rows = 2;
    LogCapture log;
    Broker broker(cfg, log.sink());
    ChildProcess worker = spawn(broker.endpoint());
    const FarmResult r = broker.run(job, deadline(120));
    broker.shutdown_workers();
    CHECK(identical(r.rgb, expected));
    for (const auto& t : r.record["tasks"]) CHECK(t["worker"] == name);
    CHECK(worker.wait_for(5));
  }
  std::remove(config.c_str());
}

TEST_CASE("farm: kill -9 of a worker mid-job: its tasks are requeued and the image is unchanged") {
  // Also a worker stopped with SIGTERM: it says bye and its tasks are requeued at once.
  const FarmJob job = small_job(64, 64, 4);
  Broker broker(ordered_broker_config(4), [](const std::string&) {});
  std::vector<ChildProcess> workers;
  for (const char* name : {"steady-1", "steady-2", "victim", "leaver"})
    workers.push_back(spawn_worker(broker.endpoint(), name, {"--throttle", "300"}));
  bool killed = false, stopped = false;
  const FarmResult r = broker.run(job, deadline(60, [&](const FarmProgress& p) {
    auto done = [&](const char* name) {
      for (const WorkerView& w : p.worker_views)
        if (w.name == name) return w.tasks;
      return 0;
    };
    // Each is stopped while it holds a task, so that task is surely lost:
    // between a result and its next task a worker holds none, and if the
    // others then finished the job before the victim's heartbeats ran out,
    // it would still count as active. At its first result: a worker gets
    // two tasks at once (its credit), so it then still holds one. (Waiting
    // for a second result failed 4 of 12 runs beside a busy render: a
    // throttled worker sleeps 300x its render time, and a preempted row
    // made each of its tasks last a second while the others took the rest.)
    auto holds_task = [&](const char* name) {
      for (const WorkerView& w : p.worker_views) {
        if (w.name == name) return w.in_flight > 0;
      }
      return false;
    };
    if (!killed && done("victim") >= 1 && holds_task("victim")) {
      workers[2].kill(SIGKILL);
      killed = true;
    }
    if (!stopped && done("leaver") >= 1 && holds_task("leaver")) {
      workers[3].kill(SIGTERM);
      stopped = true;
    }
  }));
  broker.shutdown_workers();
  REQUIRE(killed);
  REQUIRE(stopped);
  CHECK(identical(r.rgb, in_process(job)));
  const auto& victim = worker_entry(r.record, "victim");
  const auto& leaver = worker_entry(r.record, "leaver");
  CHECK(victim["state"] == "lost");
  CHECK(leaver["state"] == "left");
  CHECK(victim["tasks_lost"].get<int>() >= 1);
  CHECK(leaver["tasks_lost"].get<int>() >= 1);
  int reissued = 0, lost_attempts = 0, pixels_reissued = 0;
  for (const auto& t : r.record["tasks"]) {
    if (t["attempts"].size() < 2) continue;
    // Handed out again after its attempts were lost (a backup copy is counted apart).
    if (std::any_of(t["attempts"].begin(), t["attempts"].end(),
                    [](const auto& a) { return a["attempt"] > 1 && a["backup"] == false; })) {
      ++reissued;
      pixels_reissued += (t["y1"].get<int>() - t["y0"].get<int>()) * (t["x1"].get<int>() - t["x0"].get<int>());
    }
    const std::string first = t["attempts"][0]["worker"];
    CHECK((first == "victim" || first == "leaver"));
    for (const auto& a : t["attempts"]) {
      lost_attempts += a["outcome"] == "lost";
      CHECK(a["outcome"] == (&a == &t["attempts"].back() ? "done" : "lost"));
    }
    // The last attempt, done, may be the victim's or the leaver's too: a
    // task the other lost can reach it before its own end.
  }
  // A task can be lost twice (leaver, then victim): count attempts, not tasks.
  CHECK(lost_attempts == victim["tasks_lost"].get<int>() + leaver["tasks_lost"].get<int>());
  CHECK(reissued >= 1);
  CHECK(r.record["tasks_reissued"] == reissued);
  // Spans count their pixels' share of a row.
  const int width = r.record["settings"]["width"];
  CHECK(r.record["pixels_reissued"] == pixels_reissued);
  CHECK(r.record["rows_reissued"] == (pixels_reissued + width - 1) / width);
  CHECK(workers[3].wait_for(5));
  CHECK(describe_status(workers[3].status()) == "exit code 0");
}

TEST_CASE("farm: a worker whose terminal closes (SIGHUP) says bye as on SIGTERM, one started under nohup stays") {
  std::vector<std::string> log;  // the broker's lines; it logs from this thread (serve_for)
  Broker broker(test_broker_config(1), [&](const std::string& line) { log.push_back(line); });
  ChildProcess hung_up = spawn_worker(broker.endpoint(), "hung-up");
  // As `nohup rayfarm worker ...` starts it: SIGHUP ignored, and kept so across exec.
  ChildProcess nohup("/bin/sh", {"-c", "trap '' HUP && exec \"$@\"", "sh", test::rayfarm_exe(), "worker",
                                 "--connect", broker.endpoint(), "--name", "nohup", "--threads", "1",
                                 "--heartbeat-ms", "100", "--liveness", "5", "--quiet"});
  const auto said = [&](const std::string& who, const std::string& what) {
    return std::any_of(log.begin(), log.end(), [&](const std::string& l) {
      return l.find("worker " + who + "#") != std::string::npos && l.find(what) != std::string::npos;
    });
  };
  const auto serve_until = [&](double seconds, const std::function<bool()>& done) {
    for (const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
         !done() && std::chrono::steady_clock::now() < end;)
      broker.serve_for(0.05);
    return done();
  };
  REQUIRE(serve_until(30, [&] { return broker.progress().workers == 2; }));
  hung_up.kill(SIGHUP);
  nohup.kill(SIGHUP);
  // Told at once (it was: nothing, until its heartbeats ran out), and a clean exit.
  CHECK(serve_until(5, [&] { return said("hung-up", "said bye"); }));
  CHECK(hung_up.wait_for(5));
  CHECK(describe_status(hung_up.status()) == "exit code 0");
  // Past its liveness (5 x 100 ms): still registered, still running.
  serve_until(1.5, [] { return false; });
  CHECK(nohup.running());
  CHECK(broker.progress().workers == 1);
  CHECK_FALSE(said("nohup", "said bye"));
  CHECK_FALSE(said("nohup", "lost"));
  nohup.kill(SIGTERM);  // its other stops still work
  CHECK(nohup.wait_for(5));
  CHECK(describe_status(nohup.status()) == "exit code 0");
}

TEST_CASE("farm: a worker joining after the job started fetches the scene and contributes") {
  const FarmJob job = small_job(64, 64, 4);
  Broker broker(test_broker_config(1), [](const std::string&) {});
  std::vector<ChildProcess> workers;
  workers.push_back(spawn_worker(broker.endpoint(), "early", {"--throttle", "300"}));
  const FarmResult r = broker.run(job, deadline(60, [&](const FarmProgress& p) {
    if (workers.size() == 1 && p.rows_done >= 4) workers.push_back(spawn_worker(broker.endpoint(), "late"));
  }));
  broker.shutdown_workers();
  REQUIRE(workers.size() == 2);
  CHECK(identical(r.rgb, in_process(job)));
  const auto& late = worker_entry(r.record, "late");
  CHECK(late["rows"].get<int>() > 0);
  CHECK(late["ready_at"].get<double>() > worker_entry(r.record, "early")["ready_at"].get<double>());
}

TEST_CASE("farm: a scene whose path is not UTF-8 (Latin-1) is rendered, named with U+FFFD in the job record") {
  FarmJob job = small_job(16, 16, 1);
  job.scene_name = "sc\xe8ne.nff";
  Broker broker(test_broker_config(1), [](const std::string&) {});
  ThreadWorker worker(thread_worker_config(broker.endpoint(), "w"));
  const FarmResult r = broker.run(job, deadline(60));
  broker.shutdown_workers();
  CHECK(identical(r.rgb, in_process(job)));
  CHECK(r.record["scene"] == "sc\xef\xbf\xbdne.nff");
  CHECK_NOTHROW((void)r.record.dump());
}

TEST_CASE("farm: log lines naming a worker or scene of the longest names allowed are written whole") {
  FarmJob job = small_job(16, 16, 1);
  job.scene_name = std::string(4000, 's') + ".nff";
  LogCapture log;
  Broker broker(test_broker_config(1), log.sink());
  const std::string name(128, 'w');  // kMaxNameBytes
  ThreadWorker worker(thread_worker_config(broker.endpoint(), name));
  broker.run(job, deadline(60));
  broker.shutdown_workers();
  CHECK(log.count("worker " + name + "#1 registered: weight ") == 1);
  CHECK(log.count(", threads 1, throttle 1") == 1);
  CHECK(log.count(": " + job.scene_name + " (") == 1);
  CHECK(log.count("16x16, 1 spp, announced to 1 worker(s)") == 1);
}

TEST_CASE("farm: a broker waiting for --min-workers says how many have registered, once and on each change") {
  const FarmJob job = small_job(16, 16, 1);
  LogCapture log;
  Broker broker(test_broker_config(2), log.sink());
  std::vector<std::unique_ptr<ThreadWorker>> workers;
  auto waited_since = Clock::now();
  const FarmResult r = broker.run(job, deadline(60, [&](const FarmProgress& p) {
    // Many turns of the wait pass before each worker comes: the line is not repeated.
    if (workers.size() < 2 && p.workers == static_cast<int>(workers.size()) &&
        Clock::now() - waited_since > std::chrono::milliseconds(300)) {
      workers.push_back(std::make_unique<ThreadWorker>(
          thread_worker_config(broker.endpoint(), "w" + std::to_string(workers.size() + 1))));
      waited_since = Clock::now();
    }
  }));
  CHECK(identical(r.rgb, in_process(job)));
  CHECK(log.count("waiting for workers: 0 of the 2 needed (--min-workers)") == 1);
  CHECK(log.count("waiting for workers: 1 of the 2 needed (--min-workers)") == 1);
  CHECK(log.count("waiting for workers") == 2);
}

TEST_CASE("farm: a frame whose every row a restart restored finishes without waiting for --min-workers" *
          doctest::timeout(60)) {
  // The broker was killed while saving the frame: its journal holds every row.
  FarmJob job = small_job(16, 8, 1);
  job.restored_rgb = in_process(job);
  job.restored_rows = {{0, 5}, {5, 8}};
  LogCapture log;
  Broker broker(test_broker_config(1), log.sink());  // and no worker comes
  // Before, it waited for a worker to register, with nothing left to render.
  const FarmResult r = broker.run(job, deadline(10));
  CHECK(identical(r.rgb, job.restored_rgb));
  CHECK(r.record["resumed_rows"] == 8);
  CHECK(log.count("waiting for workers") == 0);
  // Rows missing: the wait is as before.
  job.restored_rows = {{0, 5}};
  CHECK_THROWS_WITH(broker.run(job, deadline(0.5)), "farm test deadline passed");
  CHECK(log.count("waiting for workers: 0 of the 1 needed (--min-workers)") == 1);
}

TEST_CASE("farm: --announce on the worker socket's port is named as such, not a bare 'Address already in use'") {
  const auto quiet = [](const std::string&) {};
  BrokerConfig same = test_broker_config(1);
  {
    Broker probe(same, quiet);  // a port free a moment ago, so that only the clash can fail the bind below
    same.bind = same.announce_bind = "tcp://127.0.0.1:" + std::to_string(endpoint_port(probe.endpoint()));
  }
  CHECK_THROWS_WITH_AS(Broker(same, quiet),
                       doctest::Contains("Address already in use: the worker socket (--bind) is bound to that port"),
                       InputError);
}

TEST_CASE("farm: a broker port in use in the kernel's ephemeral range says a worker may hold it (docs/deployment.md)") {
  const auto quiet = [](const std::string&) {};
  Broker first(test_broker_config(1), quiet);  // its worker port is one the kernel picked: in the ephemeral range
  BrokerConfig second = test_broker_config(1);
  second.bind = "tcp://127.0.0.1:" + std::to_string(endpoint_port(first.endpoint()));
  CHECK_THROWS_WITH_AS(Broker(second, quiet), doctest::Contains("is in the kernel's ephemeral port range"), InputError);
  CHECK_THROWS_WITH_AS(Broker(second, quiet), doctest::Contains("an outgoing connection may hold it as its own end"),
                       InputError);
}

TEST_CASE("farm: a bind address given as a host name says to bind to an IP address, not a bare 'No such device'") {
  BrokerConfig named = test_broker_config(1);
  named.announce_bind = "tcp://localhost:*";  // ZeroMQ takes the host of a bind for an interface name
  CHECK_THROWS_WITH_AS(Broker(named, [](const std::string&) {}),
                       doctest::Contains("No such device (bind to an IP address, * or an interface name"), InputError);
}

TEST_CASE("farm: a worker fetching its job in a loop is sent the scene once, not a copy per fetch") {
  // Each answer is a copy of the scene queued for the worker: 300 fetches of
  // a 4 MB scene once grew the broker by 760 MB.
  const FarmJob job = small_job(32, 16, 1);
  LogCapture log;
  BrokerConfig cfg = test_broker_config(1);
  cfg.liveness = 100;  // 10 s: every fetch below comes well within half of it
  Broker broker(cfg, log.sink());
  zmq::context_t ctx;
  RawPeer raw(ctx, broker.endpoint());
  BrokerThread run(broker, job, 30);
  const JobSpec spec = raw.join("looper", 1);
  for (int i = 0; i < 50; ++i) raw.send_message(FetchJob{spec.job});
  CHECK_FALSE(raw.wait_for<JobSpec>(1.0));
  raw.send_message(Bye{});
  ThreadWorker real(thread_worker_config(broker.endpoint(), "real"));
  run.join();
  REQUIRE(run.error.empty());
  CHECK(identical(run.result.rgb, in_process(job)));
  CHECK(run.result.record["rejected"]["refetch"] == 50);
  CHECK(log.count("rejected fetch of job " + std::to_string(spec.job) + " from looper#1 within 5000 ms of the copy "
                  "sent to it: not sent again") == 20);  // then the rate limit of rejections
}

TEST_CASE("farm: malformed messages to the broker are rejected and logged, and it keeps serving") {
  const FarmJob job = small_job(32, 16, 1);
  LogCapture log;
  Broker broker(test_broker_config(0), log.sink());
  zmq::context_t ctx;
  RawPeer raw(ctx, broker.endpoint());
  BrokerThread run(broker, job, 30);

  const Frames ready = encode(Message{Ready{"raw", 21.0, 1, 1, 100, 1.0}});
  TaskResult res;
  res.job = 1;
  res.y0 = 0;
  res.y1 = 1;
  res.width = 32;
  res.x1 = 32;
  res.rgb.assign(32 * 3, 0.5f);
  Frames truncated = encode(Message{res});
  truncated[0].resize(truncated[0].size() - 7);
  Frames huge = encode(Message{res});
  const uint32_t big = 65536;
  std::memcpy(&huge[0][28], &big, 4);  // claims 65536 rows in a 488-byte frame
  const std::vector<Frames> garbage = {
      {""},
      {ready[0], "x", "y"},
      {"{not json"},
      {R"({"v":2,"type":"ready"})"},
      {R"({"v":4,"type":"gimme"})"},
      truncated,
      huge,
  };
  for (const Frames& f : garbage) raw.send_frames(f);
  raw.alive = false;
  // The one of another protocol version is answered, so such a worker can say why it is refused.
  const auto refused = raw.wait_for<Reregister>(5);
  REQUIRE(refused);
  CHECK(refused->reason == "refused: v: unsupported protocol version 2 (this is 4)");
  // A well-formed message from a peer that never registered: told to re-register.
  raw.send_message(Heartbeat{0});
  CHECK(raw.wait_for<Reregister>(5));
  raw.alive = true;
  // Registered, then a message only brokers send.
  raw.send_message(Ready{"raw", 21.0, 1, 1, 100, 1.0});
  CHECK(raw.wait_for<Welcome>(5));
  raw.send_message(TaskAssign{1, 0, 1, 0, 1, 0, 32});
  raw.send_message(Bye{});

  ThreadWorker real(thread_worker_config(broker.endpoint(), "real"));
  run.join();
  REQUIRE(run.error.empty());
  CHECK(identical(run.result.rgb, in_process(job)));
  // Job-scoped counters start with the job, which began before the garbage arrived.
  CHECK(run.result.record["rejected"]["malformed"] == static_cast<int>(garbage.size()));
  CHECK(run.result.record["rejected"]["unknown_worker"] == 1);
  CHECK(run.result.record["rejected"]["unexpected"] == 1);
  CHECK(log.count("rejected message from unknown peer: ") == static_cast<int>(garbage.size()));
  CHECK(log.count("unsupported protocol version 2") == 1);
  CHECK(log.count("unknown message type 'gimme'") == 1);
  CHECK(log.count("rows * (x1 - x0) * 3 * 4 + 112") == 2);
}

TEST_CASE("farm: a flood of readies from one peer logs a few lines a second and leaves the job record one entry") {
  // Each `ready` logged two lines unlimited and left a worker record in the job:
  // 130,000 of them grew the broker by 44 MB.
  const FarmJob job = small_job(32, 16, 1);
  LogCapture log;
  Broker broker(test_broker_config(0), log.sink());
  zmq::context_t ctx;
  RawPeer flood(ctx, broker.endpoint());
  BrokerThread run(broker, job, 30);
  constexpr int kReadies = 400;
  for (int i = 0; i < kReadies; ++i) flood.send_message(Ready{"flood", 21.0, 1, 4, 100, 1.0});
  for (int i = 0; i < kReadies; ++i) REQUIRE(flood.wait_for<Welcome>(5));
  flood.send_message(Bye{});
  flood.alive = false;

  ThreadWorker real(thread_worker_config(broker.endpoint(), "real"));
  run.join();
  REQUIRE(run.error.empty());
  CHECK(identical(run.result.rgb, in_process(job)));
  const auto& workers = run.result.record["workers"];
  REQUIRE(workers.size() == 1);  // the worker that rendered, as before
  CHECK(workers[0]["name"] == "real");
  CHECK(workers[0]["tasks"].get<int>() > 0);
  CHECK(run.result.record["registrations_without_tasks"] == kReadies);
  // Capped at 20 re-registration lines a second; what was held back is
  // counted. A new worker's registration is not among what is held back.
  CHECK(log.count("worker flood#") < kReadies / 4);
  CHECK(log.count("more re-registrations not shown)") >= 1);
  CHECK(log.count("worker real#") == 1);
}

TEST_CASE("farm: a re-registration held back by the rate limit still says the tasks it requeued") {
  // Its "requeued N task(s)" went with its line: work moved back to the queue
  // without a word, while a flood of readies from another peer filled the second.
  const FarmJob job = small_job(32, 16, 1);
  LogCapture log;
  BrokerConfig cfg = ordered_broker_config(0);
  cfg.liveness = 100;  // 10 s: nobody is lost meanwhile
  Broker broker(cfg, log.sink());
  zmq::context_t ctx;
  RawPeer holder(ctx, broker.endpoint()), flood(ctx, broker.endpoint());
  BrokerThread run(broker, job, 30);
  holder.join("holder", 2);
  REQUIRE(holder.wait_for<TaskAssign>(5));
  REQUIRE(holder.wait_for<TaskAssign>(5));
  // 60 readies in some 0.1 s: the second's 20 lines are gone before the holder's
  // (unless the second turns at the last third of the flood: then it is shown).
  constexpr int kReadies = 60;
  for (int i = 0; i < kReadies; ++i) flood.send_message(Ready{"flood", 21.0, 1, 1, 100, 1.0});
  for (int i = 0; i < kReadies; ++i) REQUIRE(flood.wait_for<Welcome>(5));
  holder.send_message(Ready{"holder", 21.0, 1, 2, 100, 1.0});
  REQUIRE(holder.wait_for<Welcome>(5));
  holder.send_message(Bye{});
  flood.send_message(Bye{});
  holder.alive = flood.alive = false;
  ThreadWorker real(thread_worker_config(broker.endpoint(), "real"));
  run.join();
  REQUIRE(run.error.empty());
  CHECK(identical(run.result.rgb, in_process(job)));
  CHECK(worker_entry(run.result.record, "holder")["tasks_lost"] == 2);
  // Its own line, or the count of those held back, says the two tasks.
  CHECK(log.count("worker holder#1 re-registered, requeued 2 task(s)") +
            log.count("more re-registrations not shown; they requeued 2 task(s))") ==
        1);
}

TEST_CASE("farm: 100 workers complete a job and no worker gets a second task while a ready one has none") {
  const FarmJob job = small_job(32, 160, 1);
  zmq::context_t ctx(2);
  BrokerConfig cfg = ordered_broker_config(100);
  cfg.heartbeat_ms = 500;  // 100 workers on 2 cores: leave room for the heartbeats
  Broker broker(cfg, [](const std::string&) {});
  std::vector<std::unique_ptr<ThreadWorker>> workers;
  for (int i = 0; i < 100; ++i) {
    WorkerConfig c = thread_worker_config(broker.endpoint(), "w" + std::to_string(i));
    c.heartbeat_ms = 500;
    c.credit = 1;
    c.throttle = 50;  // stretch the tiny tasks so the workers overlap
    workers.push_back(std::make_unique<ThreadWorker>(c, &ctx));
  }
  const FarmResult r = broker.run(job, deadline(90));
  broker.shutdown_workers();
  workers.clear();
  CHECK(identical(r.rgb, in_process(job)));
  REQUIRE(r.record["workers"].size() == 100);
  // Demand-driven dispatch after a static start: a worker's second task is never
  // dispatched before the first task of any worker that was ready by then.
  std::map<std::string, std::vector<double>> dispatched;
  for (const auto& t : r.record["tasks"])
    for (const auto& a : t["attempts"]) dispatched[a["worker"]].push_back(a["dispatched"]);
  std::map<std::string, double> ready_at;
  for (const auto& w : r.record["workers"]) ready_at[w["name"]] = w["ready_at"];
  int contributed = 0, violations = 0;
  for (auto& [name, times] : dispatched) {
    std::sort(times.begin(), times.end());
    contributed += !times.empty();
  }
  for (const auto& [name, times] : dispatched) {
    if (times.size() < 2) continue;
    for (const auto& [other, ready] : ready_at) {
      if (ready < 0 || ready >= times[1]) continue;
      const auto it = dispatched.find(other);
      violations += it == dispatched.end() || it->second.front() > times[1];
    }
  }
  CHECK(violations == 0);
  MESSAGE(contributed << " of 100 workers rendered rows");
}

TEST_CASE("farm: two workers sharing a name are told apart in the job record as the log tells them apart") {
  // The log said twin#1 and twin#2, the record "twin" twice.
  LogCapture log;
  BrokerConfig cfg = test_broker_config(2);
  Broker broker(cfg, log.sink());
  ThreadWorker a(thread_worker_config(broker.endpoint(), "twin")), b(thread_worker_config(broker.endpoint(), "twin"));
  const FarmJob job = small_job(32, 16, 1);
  const FarmResult r = broker.run(job, deadline(30));
  CHECK(identical(r.rgb, in_process(job)));
  REQUIRE(r.record["workers"].size() == 2);
  std::set<std::string> ids;
  for (const auto& w : r.record["workers"]) {
    CHECK(w["name"] == "twin");  // kept: readers of older records group by it
    const std::string id = w.value("id", std::string());
    ids.insert(id);
    CHECK(log.count("worker " + id + " registered") == 1);
  }
  CHECK(ids == std::set<std::string>{"twin#1", "twin#2"});
  for (const auto& t : r.record["tasks"]) {
    CHECK(t["worker"] == "twin");
    CHECK(ids.count(t.value("worker_id", std::string())) == 1);
    for (const auto& attempt : t["attempts"]) CHECK(ids.count(attempt.value("worker_id", std::string())) == 1);
  }
  broker.shutdown_workers();
}

TEST_CASE("farm: two workers sharing a name have a task count each in the job's progress, not one summed") {
  // The counts were kept by name: the twins showed as one worker doing both's tasks.
  Broker broker(test_broker_config(2), [](const std::string&) {});
  ThreadWorker a(thread_worker_config(broker.endpoint(), "twin")), b(thread_worker_config(broker.endpoint(), "twin"));
  const FarmJob job = small_job(32, 16, 1);
  std::map<std::string, int> last;
  const FarmResult r = broker.run(job, deadline(30, [&](const FarmProgress& p) { last = p.tasks_done; }));
  broker.shutdown_workers();
  CHECK(identical(r.rgb, in_process(job)));
  REQUIRE(r.record["workers"].size() == 2);
  std::map<std::string, int> recorded;
  for (const auto& w : r.record["workers"]) recorded[w["id"].get<std::string>()] = w["tasks"].get<int>();
  // The last watch may come before the last result: each count is at most the record's.
  REQUIRE(last.size() == 2);
  for (const auto& [id, tasks] : last) {
    REQUIRE(recorded.count(id) == 1);
    CHECK(tasks <= recorded[id]);
  }
}

TEST_CASE("farm: a worker known gone by name is dropped in every registration of it, and local names are unique") {
  // A local worker that reconnected is registered twice until its old socket
  // times out; when its process exited, only the first registration found was
  // dropped, and the other held its tasks for a heartbeat timeout.
  LogCapture log;
  Broker broker(test_broker_config(0), log.sink());
  zmq::context_t ctx(1);
  RawPeer old_socket(ctx, broker.endpoint()), new_socket(ctx, broker.endpoint()), other(ctx, broker.endpoint());
  old_socket.send_message(Ready{"local-1", 21.0, 1, 1, 1000, 1.0});
  new_socket.send_message(Ready{"local-1", 21.0, 1, 1, 1000, 1.0});
  other.send_message(Ready{"local-2", 21.0, 1, 1, 1000, 1.0});
  for (int i = 0; i < 50 && broker.worker_count() < 3; ++i) broker.serve_for(0.02);
  REQUIRE(broker.worker_count() == 3);
  broker.drop_worker("local-1", "exited (killed by signal 9): lost");
  CHECK(broker.worker_count() == 1);  // was 2
  CHECK(log.count("exited (killed by signal 9): lost") == 2);
  CHECK(log.count("worker local-2#") == 1);  // its registration line only
  // So a local farm's names must each be one process's.
  LocalFarmOptions o;
  o.machines = {{"twin", 21.0, 1.0}, {"twin", 21.0, 2.0}};
  o.executable = test::rayfarm_exe();  // never this test binary, should the farm start
  o.deadline_s = 20;
  o.progress = false;
  const FarmJob job = small_job(16, 16, 1);
  CHECK_THROWS_WITH_AS(render_local_farm(job.scene_text, job.scene_name, job.settings, o),
                       doctest::Contains("two workers named 'twin'"), std::invalid_argument);
}
