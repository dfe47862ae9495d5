// Local farm tests: `render --workers N` and `worker --lab`, a broker in this
// process and real `rayfarm worker` child processes on loopback; what the
// farm does when a child is killed, exits early, or shares a Ctrl-C with a
// script. Every image is compared bit for bit with the in-process render.
#include <doctest/doctest.h>

#include <signal.h>
#include <sys/types.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <memory>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "broker/child_process.h"
#include "broker/farm_render_job.h"
#include "broker/local_farm.h"
#include "tests/farm_peers.h"
#include "tests/run_command.h"
#include "tests/test_files.h"
#include "tests/test_paths.h"
#include "tracer/image_io.h"
#include "tracer/renderer.h"
#include "worker/lab.h"
using namespace rayfarm;
using namespace rayfarm::test;
using Clock = std::chrono::steady_clock;

namespace {

// A local farm of two one-thread `rayfarm worker` processes, quiet.
LocalFarmOptions two_local_workers() {
  LocalFarmOptions o;
  o.workers = 2;
  o.threads = 1;
  o.executable = test::rayfarm_exe();
  o.progress = false;
  return o;
}

// The children of `parent` (default: this process): their pids and command
// lines, arguments joined by spaces.
std::vector<std::pair<pid_t, std::string>> child_processes(pid_t parent = getpid()) {
  std::vector<std::pair<pid_t, std::string>> children;
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator("/proc", ec)) {
    std::ifstream stat(entry.path() / "stat");
    std::string text;
    std::getline(stat, text);
    const size_t comm_end = text.rfind(')');  // "pid (comm) state ppid ..."
    if (comm_end == std::string::npos) continue;
    std::istringstream fields(text.substr(comm_end + 1));
    char state = 0;
    pid_t ppid = 0;
    if (!(fields >> state >> ppid) || ppid != parent) continue;
    std::ifstream cmdline(entry.path() / "cmdline");
    std::string args((std::istreambuf_iterator<char>(cmdline)), std::istreambuf_iterator<char>());
    std::replace(args.begin(), args.end(), '\0', ' ');
    children.emplace_back(static_cast<pid_t>(std::stol(entry.path().filename().string())), args);
  }
  return children;
}

// A one-thread render of `scene_path` at width x height and spp, written to
// `output_path`: the job the local-farm tests run both ways.
RenderJob small_render_job(const std::string& scene_path, int width, int height, int spp,
                           const std::string& output_path) {
  RenderJob job;
  job.scene_path = scene_path;
  job.overrides.width = width;
  job.overrides.height = height;
  job.overrides.spp = spp;
  job.overrides.threads = 1;
  job.output_path = output_path;
  return job;
}

}  // namespace

TEST_CASE("farm: render --workers --max-isa caps the local workers' SIMD width as it caps the process's") {
  // The cap is a worker's own (its config or --max-isa), not the job's: the
  // local farm's workers ran at full width.
  const std::string dir = "/tmp/rayfarm-farm-max-isa-" + std::to_string(getpid());
  std::filesystem::create_directories(dir);
  RenderJob job = small_render_job(test::spd_data("balls-1"), 16, 16, 1, dir + "/farm.exr");
  job.overrides.max_isa = "sse2";
  LocalFarmOptions o = two_local_workers();
  std::set<std::string> workers;  // their command lines, seen while the job runs
  o.watch = [&](const FarmProgress&) {
    for (const auto& [pid, line] : child_processes())
      if (line.find(" worker ") != std::string::npos) workers.insert(line);
  };
  run_render_job_on_local_farm(job, o);
  REQUIRE(workers.size() == 2);
  for (const std::string& line : workers) {
    CAPTURE(line);
    CHECK(line.find(" --max-isa sse2") != std::string::npos);
  }
  std::filesystem::remove_all(dir);
}

TEST_CASE("farm: render --workers whose threads outnumber the machine's warns that they only share them") {
  // 64 workers on 2 cores rendered some 6 times slower than 2, without a
  // word; and workers of several threads each were counted as one thread:
  // two workers of every core (--threads 0, the default) shared them silently.
  const std::string dir = "/tmp/rayfarm-farm-many-" + std::to_string(getpid());
  std::filesystem::create_directories(dir);
  const RenderJob job = small_render_job(test::spd_data("balls-1"), 8, 8, 1, dir + "/farm.png");
  std::vector<std::string> warnings;
  RenderCallbacks callbacks;
  callbacks.warning = [&](const std::string& w) { warnings.push_back(w); };
  LocalFarmOptions o = two_local_workers();
  const int machine = render_threads(0);
  const std::string n = std::to_string(machine);
  o.workers = machine;  // one thread each: no warning
  run_render_job_on_local_farm(job, o, callbacks);
  o.workers = 1;  // one worker of every thread: no warning
  o.threads = 0;
  run_render_job_on_local_farm(job, o, callbacks);
  CHECK(warnings.empty());
  o.workers = machine + 1;
  o.threads = 1;
  run_render_job_on_local_farm(job, o, callbacks);
  o.workers = 2;
  o.threads = 0;
  run_render_job_on_local_farm(job, o, callbacks);
  CHECK(warnings ==
        std::vector<std::string>{
            "--workers " + std::to_string(machine + 1) + " with --threads 1: " + std::to_string(machine + 1) +
                " render threads, and this machine runs " + n + " at once; the workers share them and render no "
                "faster than " + n + " threads would",
            "--workers 2 with --threads 0 (all " + n + " of this machine's threads each): " +
                std::to_string(2 * machine) + " render threads, and this machine runs " + n +
                " at once; the workers share them and render no faster than " + n + " threads would" +
                (machine >= 2 ? "; --threads " + std::to_string(machine / 2) + " gives each worker its share" : "")});
  std::filesystem::remove_all(dir);
}

TEST_CASE("farm: adaptive sampling and the cutoff travel with the job") {
  const std::string dir = "/tmp/rayfarm-farm-knobs-" + std::to_string(getpid());
  std::filesystem::create_directories(dir);
  RenderJob job =
      small_render_job(test::source_dir() + "/scenes/balls.nff", 48, 32, 16, dir + "/in-process.exr");
  job.overrides.adaptive_contrast = 0.2;
  job.overrides.cutoff = 0.01;
  const RenderReport local = run_render_job(job);

  const LocalFarmOptions o = two_local_workers();
  job.output_path = dir + "/farm.exr";
  const RenderReport farm = run_render_job_on_local_farm(job, o, {}, dir + "/record.json");
  CHECK(identical(read_image(dir + "/farm.exr").rgb, read_image(dir + "/in-process.exr").rgb));
  CHECK(farm.rays.eye == local.rays.eye);
  CHECK(farm.rays.reflection == local.rays.reflection);
  CHECK(local.rays.eye < 48u * 32u * 16u);  // adaptive: not every pixel refined
  std::ifstream record_file(dir + "/record.json");
  const nlohmann::json record = nlohmann::json::parse(record_file);
  CHECK(record["settings"]["cutoff"] == 0.01);
  CHECK(record["settings"]["adaptive_contrast"] == 0.2);
  std::filesystem::remove_all(dir);
}

TEST_CASE("farm: render --workers 2 writes the same image and ray counts as the in-process render") {
  const std::string dir = "/tmp/rayfarm-farm-test-" + std::to_string(getpid());
  std::filesystem::create_directories(dir);
  RenderJob job = small_render_job(test::spd_data("balls-2"), 64, 32, 4, dir + "/in-process.exr");
  job.stats_path = dir + "/in-process.json";
  const RenderReport local = run_render_job(job);

  const LocalFarmOptions o = two_local_workers();
  job.output_path = dir + "/farm.exr";
  job.stats_path = dir + "/farm.json";
  const RenderReport farm = run_render_job_on_local_farm(job, o, {}, dir + "/record.json");

  CHECK(identical(read_image(dir + "/farm.exr").rgb, read_image(dir + "/in-process.exr").rgb));
  CHECK(farm.rays.total() == local.rays.total());
  CHECK(farm.rays.shadow == local.rays.shadow);
  std::ifstream record_file(dir + "/record.json");
  const nlohmann::json record = nlohmann::json::parse(record_file);
  CHECK(record["workers"].size() == 2);
  CHECK(record["settings"]["width"] == 64);
  job.rows = RowRange{0, 8};
  CHECK_THROWS_AS(run_render_job_on_local_farm(job, o), InputError);
  std::filesystem::remove_all(dir);
}

TEST_CASE("farm: broker --stats counts the threads of the workers that rendered, not the broker's cores") {
  // It said the broker machine's core count, and the job record said 0 for a
  // worker on all its cores.
  const std::string dir = "/tmp/rayfarm-farm-threads-" + std::to_string(getpid());
  std::filesystem::create_directories(dir);
  RenderJob job = small_render_job(test::spd_data("balls-2"), 64, 32, 4, dir + "/farm.exr");
  job.overrides.threads = 0;  // the broker's own: it renders nothing
  job.stats_path = dir + "/stats.json";
  BrokerJobOptions o;
  o.config = test_broker_config(2);
  o.record_path = dir + "/record.json";
  o.log = [](const std::string&) {};
  std::vector<std::unique_ptr<ThreadWorker>> workers;
  o.listening = [&](const Broker& broker) {
    WorkerConfig one = thread_worker_config(broker.endpoint(), "one");
    WorkerConfig all = thread_worker_config(broker.endpoint(), "all");
    one.threads = 3;
    all.threads = 0;  // every core
    workers.push_back(std::make_unique<ThreadWorker>(one));
    workers.push_back(std::make_unique<ThreadWorker>(all));
  };
  run_render_job_on_broker(job, o);
  workers.clear();
  std::ifstream record_file(dir + "/record.json"), stats_file(dir + "/stats.json");
  const nlohmann::json record = nlohmann::json::parse(record_file), stats = nlohmann::json::parse(stats_file);
  int rendering = 0;
  for (const auto& w : record["workers"]) {
    CAPTURE(w["name"]);
    CHECK(w["threads"] == render_threads(w["name"] == "one" ? 3 : 0));
    if (w["tasks"].get<int>() > 0) rendering += w["threads"].get<int>();
  }
  CHECK(rendering > 0);
  CHECK(stats["threads"] == rendering);
  std::filesystem::remove_all(dir);
}

TEST_CASE("farm: broker --shutdown-workers sends its workers away also when -o cannot be written") {
  // They were told only after the image was written: a broker that failed
  // there left the workers started for its one job waiting for it forever.
  const std::string dir = "/tmp/rayfarm-farm-shutdown-" + std::to_string(getpid());
  std::filesystem::create_directories(dir + "/out");
  const RenderJob job = small_render_job(test::spd_data("balls-1"), 16, 16, 1, dir + "/out/farm.png");
  BrokerJobOptions o;
  o.config = test_broker_config(1);
  o.shutdown_workers = true;
  o.log = [](const std::string&) {};
  std::unique_ptr<ThreadWorker> worker;
  o.listening = [&](const Broker& broker) {
    worker = std::make_unique<ThreadWorker>(thread_worker_config(broker.endpoint(), "one"));
    std::filesystem::remove_all(dir + "/out");  // checked writable, gone when the image is done
  };
  CHECK_THROWS_WITH_AS(run_render_job_on_broker(job, o), doctest::Contains("farm.png: cannot write"), InputError);
  REQUIRE(worker);
  const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  while (!worker->exited && std::chrono::steady_clock::now() < end)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  CHECK(worker->exited);  // on its own: finish() below would stop it
  worker->finish();
  std::filesystem::remove_all(dir);
}

TEST_CASE("farm: heartbeats keep flowing while a worker renders one long task on every core") {
  // One task of 128 rows at 576 spp lasts twice the 5 x 100 ms a silent worker
  // is allowed (1.1 s on two cores); one whose socket loop waited for the
  // tracer would be lost. (40 ms heartbeats failed on a loaded machine: the
  // render threads on every core starved the socket thread of more than 200 ms
  // of CPU.)
  FarmJob job = small_job(192, 128, 576);
  BrokerConfig cfg = ordered_broker_config(1);
  cfg.heartbeat_ms = 100;
  cfg.base_task_rows = 128;
  Broker broker(cfg, [](const std::string&) {});
  WorkerConfig c = thread_worker_config(broker.endpoint(), "busy");
  c.threads = 0;  // all cores
  c.heartbeat_ms = 100;
  c.credit = 1;
  ThreadWorker worker(c);
  const FarmResult r = broker.run(job, deadline(60));
  const auto& busy = worker_entry(r.record, "busy");
  REQUIRE(r.record["tasks"].size() == 1);
  MESSAGE("one task rendered in " << r.record["tasks"][0]["render_s"] << " s");
  CHECK(r.record["tasks"][0]["render_s"].get<double>() > 5 * 0.1);
  CHECK(busy["state"] == "active");
  CHECK(busy["tasks_lost"] == 0);
  CHECK(r.record["tasks_reissued"] == 0);
  broker.shutdown_workers();
}

TEST_CASE("farm: the local farm fails with a clear error when its workers cannot start") {
  const FarmJob job = small_job(16, 16, 1);
  LocalFarmOptions o;
  o.workers = 3;
  // A rayfarm that exits at once, like a worker that cannot run.
  const std::filesystem::path fake = scratch_dir("farm-false") / "rayfarm";
  write_file(fake, "#!/bin/sh\nexit 1\n");
  std::filesystem::permissions(fake, std::filesystem::perms::owner_all);
  o.executable = fake.string();
  o.progress = false;
  const auto t0 = Clock::now();
  try {
    render_local_farm(job.scene_text, job.scene_name, job.settings, o);
    FAIL("the local farm rendered without workers");
  } catch (const std::runtime_error& e) {
    // Whichever exit the farm sees first: they all exit at once.
    const std::string what = e.what();
    CHECK(what.rfind("local worker local-", 0) == 0);
    CHECK(what.find(" exited before the job started (exit code 1)") != std::string::npos);
  }
  CHECK(Clock::now() - t0 < std::chrono::seconds(10));
}

TEST_CASE("farm: the local farm refuses a worker executable that is not rayfarm, such as the test binary") {
  // Started from the tests without its executable set, the farm ran the test
  // binary itself as each worker, and every one of them ran the whole suite.
  const FarmJob job = small_job(16, 16, 1);
  LocalFarmOptions o;
  o.workers = 2;
  o.progress = false;
  const std::string self = self_executable();
  CHECK_THROWS_WITH_AS(render_local_farm(job.scene_text, job.scene_name, job.settings, o),
                       ("local farm: the worker executable " + self + " is not rayfarm (its file name is " +
                        std::filesystem::path(self).filename().string() +
                        ", expected rayfarm or rayfarm-*); set LocalFarmOptions::executable to the rayfarm binary")
                           .c_str(),
                       std::invalid_argument);
  o.executable = "/bin/true";
  CHECK_THROWS_WITH_AS(render_local_farm(job.scene_text, job.scene_name, job.settings, o),
                       doctest::Contains("the worker executable /bin/true is not rayfarm"), std::invalid_argument);
}

TEST_CASE("farm: render --workers started with SIGINT ignored finishes through a Ctrl-C, as its workers ignore it too") {
  // A script's background job: the shell ignores SIGINT for it, and a Ctrl-C
  // at the terminal reaches the render and its workers alike. The render
  // carried on, but its workers quit, and it failed: "all 2 local workers exited".
  const std::string dir = "/tmp/rayfarm-farm-sigint-" + std::to_string(getpid());
  std::filesystem::create_directories(dir);
  std::signal(SIGINT, SIG_IGN);  // inherited by the render and, through it, its workers
  ChildProcess render(test::rayfarm_exe(), {"render", test::paper_scene("rings"), "-o", dir + "/rings.png", "--width",
                                            "256", "--spp", "64", "--threads", "1", "--workers", "2"});
  std::signal(SIGINT, SIG_DFL);
  std::vector<pid_t> workers;
  const auto end = Clock::now() + std::chrono::seconds(30);
  while (workers.size() < 2 && Clock::now() < end) {
    workers.clear();
    for (const auto& [pid, line] : child_processes(render.pid()))
      if (line.find(" worker ") != std::string::npos) workers.push_back(pid);
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  REQUIRE(workers.size() == 2);
  render.kill(SIGINT);
  for (const pid_t pid : workers) ::kill(pid, SIGINT);
  REQUIRE(render.wait_for(60));
  CHECK(describe_status(render.status()) == "exit code 0");
  CHECK(std::filesystem::exists(dir + "/rings.png"));
  std::filesystem::remove_all(dir);
}

TEST_CASE("farm: a local worker that exits before the job starts ends the render with its name, not a wait forever") {
  // The broker waits for every local worker to register; "early" exits at
  // start (a throttle its command line refuses) and never will.
  const FarmJob job = small_job(16, 16, 1);
  LocalFarmOptions o = two_local_workers();
  o.machines = {{"steady", 21.0, 1.0}, {"early", 21.0, 0.5}};
  o.deadline_s = 30;
  const auto t0 = Clock::now();
  try {
    render_local_farm(job.scene_text, job.scene_name, job.settings, o);
    FAIL("the local farm rendered without its second worker");
  } catch (const std::runtime_error& e) {
    CHECK(std::string(e.what()) == "local worker early exited before the job started (exit code 1)");
  }
  CHECK(Clock::now() - t0 < std::chrono::seconds(10));
}

TEST_CASE("farm: render --workers raises the open-file limit its workers' connections need, or says it cannot") {
  // The broker holds two connections per worker. Under a soft limit too low
  // for them, some workers never connected and the render waited for them
  // forever, silently.
  const std::string dir = std::filesystem::temp_directory_path() / ("rayfarm-open-files-" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  const std::string render = "timeout 60 " + test::rayfarm_exe() + " render " + test::spd_data("tetra-1") + " -o " +
                             dir + "/x.png --width 16 --spp 1 --threads 1 --workers 40";
  const CommandResult raised = run_command("ulimit -Sn 64 && " + render);
  CHECK(raised.exit_code == 0);
  CHECK(std::filesystem::exists(dir + "/x.png"));
  // `ulimit -n` lowers the hard limit too, which the render cannot raise.
  const CommandResult refused = run_command("ulimit -n 64 && " + render);
  CHECK(refused.exit_code == 1);
  CHECK(refused.output.find("rayfarm: a local farm of 40 workers needs about 224 open files, but this process may "
                            "open at most 64 (RLIMIT_NOFILE hard limit; see `ulimit -Hn`): use fewer --workers or "
                            "raise the limit") != std::string::npos);
  std::filesystem::remove_all(dir);
}

TEST_CASE("farm: broker raises its open-file limit for the workers that connect, or says it cannot") {
  // Each worker holds two connections to the broker. Under a soft limit of 40
  // files, 17 of 20 workers registered and a broker waiting for all 20
  // waited forever, silently.
  const std::string dir = std::filesystem::temp_directory_path() / ("rayfarm-broker-files-" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  const std::string broker = test::rayfarm_exe() + " broker " + test::spd_data("tetra-1") + " -o " + dir +
                             "/x.png --width 16 --spp 1 --bind 'tcp://127.0.0.1:*' --announce 'tcp://127.0.0.1:*'";
  // The soft limit up to the hard one, read from the waiting broker's /proc/PID/limits.
  const CommandResult raised = run_command(
      "ulimit -Sn 40 && " + broker + " --min-workers 2 > " + dir + "/broker.log 2>&1 & pid=$!; " +
      "for i in $(seq 200); do grep -q 'workers connect' " + dir + "/broker.log && break; sleep 0.05; done; " +
      "awk '/Max open files/ { print ($4 == $5 ? \"raised\" : \"soft \" $4 \" hard \" $5) }' /proc/$pid/limits; "
      "kill $pid; wait $pid");
  CHECK(raised.output.rfind("raised\n", 0) == 0);  // then the shell's "Terminated"
  // `ulimit -n` lowers the hard limit too: the workers waited for cannot all connect.
  const CommandResult refused = run_command("ulimit -n 64 && timeout 30 " + broker + " --min-workers 40");
  CHECK(refused.exit_code == 1);
  CHECK(refused.output ==
        "rayfarm: a broker waiting for 40 workers (--min-workers) needs about 224 open files, but this process may "
        "open at most 64 (RLIMIT_NOFILE hard limit; see `ulimit -Hn`): wait for fewer workers or raise the hard "
        "limit (`ulimit -Hn`, or LimitNOFILE= of a systemd service)\n");
  std::filesystem::remove_all(dir);
}

TEST_CASE("farm: broker --serve refuses at start an --http-connections its open-file limit cannot hold") {
  // Each HTTP connection holds a file. Under a hard limit of 128 and the
  // default cap of 512, 150 clients took every file before any was answered
  // 503, and a submission failed: "last-id: cannot write (Too many open files)".
  const std::string dir = std::filesystem::temp_directory_path() / ("rayfarm-http-files-" + std::to_string(getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::string broker = test::rayfarm_exe() + " broker --serve --state " + dir + "/state --http 127.0.0.1:0 " +
                             "--bind 'tcp://127.0.0.1:*' --announce 'tcp://127.0.0.1:*'";
  const CommandResult refused = run_command("ulimit -n 256 && timeout 30 " + broker);
  CHECK(refused.exit_code == 1);
  CHECK(refused.output ==
        "rayfarm: an HTTP API of 512 connections (--http-connections) beside 1 worker waited for needs about 580 open "
        "files, but this process may open at most 256 (RLIMIT_NOFILE hard limit; see `ulimit -Hn`): give "
        "--http-connections 188 or fewer or raise the hard limit (`ulimit -Hn`, or LimitNOFILE= of a systemd "
        "service)\n");
  CHECK(!std::filesystem::exists(dir + "/state"));  // refused before the state folder is made
  CHECK(run_command("ulimit -n 256 && timeout 30 " + broker + " --min-workers 8 --http-connections 188").output.find(
            "--http-connections 160 or fewer") != std::string::npos);
  // What fits starts.
  const CommandResult fits = run_command(
      "(ulimit -n 256 && exec " + broker + " --http-connections 188) > " + dir + "/broker.log 2>&1 & pid=$!; " +
      "for i in $(seq 200); do grep -q 'serving http' " + dir + "/broker.log && break; sleep 0.05; done; " +
      "kill $pid; wait $pid; cat " + dir + "/broker.log");
  CHECK(fits.output.find("rayfarm broker: serving http://127.0.0.1:") != std::string::npos);
  std::filesystem::remove_all(dir);
}

TEST_CASE("farm: a broker out of files for the workers that connect says so, not only the workers' key advice") {
  // More workers than its open-file limit holds connected: they were turned
  // away in the handshake and logged advice about keys and ports, while the
  // broker said nothing, then failed to open its image with "cannot open the file".
  const std::string dir = std::filesystem::temp_directory_path() / ("rayfarm-broker-emfile-" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  std::ofstream(dir + "/lab.json") << R"({"machines": [{"weight": 21, "count": 100, "throttle": 1000}]})";
  const std::string log = dir + "/broker.log";
  const CommandResult r = run_command(
      "(ulimit -n 80 && exec timeout 30 " + test::rayfarm_exe() + " broker " + test::spd_data("tetra-1") + " -o " +
      dir + "/x.png --width 64 --spp 16 --min-workers 1 --no-progress --bind 'tcp://127.0.0.1:*' --announce "
      "'tcp://127.0.0.1:*') > " + log + " 2>&1 & broker=$!; "
      "for i in $(seq 200); do grep -q 'workers connect' " + log + " && break; sleep 0.05; done; "
      "ep=$(sed -n 's/.*workers connect to \\(tcp:[^ ]*\\) .*/\\1/p' " + log + "); "
      "timeout 30 " + test::rayfarm_exe() + " worker --lab " + dir + "/lab.json --connect $ep --threads 1 --quiet "
      "> /dev/null 2>&1 & lab=$!; wait $broker; kill $lab; wait $lab; cat " + log);
  CHECK(r.output.find("cannot accept a connection on tcp://127.0.0.1:") != std::string::npos);
  CHECK(r.output.find(": Too many open files; this broker may open 80 (RLIMIT_NOFILE; each worker holds two "
                      "connections): workers beyond that never register") != std::string::npos);
  std::filesystem::remove_all(dir);
}

TEST_CASE("farm: a local worker killed mid-job is dropped as soon as its process exits, not after its heartbeats") {
  // Heartbeats would notice the loss only after 60 s: the farm sees the exit of
  // its own child and requeues its tasks at once.
  const FarmJob job = small_job(64, 64, 4);
  LocalFarmOptions o = two_local_workers();
  o.machines = {{"steady", 21.0, 1.0}, {"victim", 21.0, 1000.0}};  // holds its first task for long
  o.heartbeat_ms = 1000;
  o.liveness = 60;
  o.deadline_s = 40;
  o.policy = PolicyKind::paper;  // no backups: the victim's tasks come back only by its loss
  LogCapture log;
  o.log = log.sink();
  bool killed = false;
  o.watch = [&](const FarmProgress& p) {
    if (killed) return;
    for (const WorkerView& w : p.worker_views) {
      if (w.name != "victim" || w.in_flight < 1) continue;
      for (const auto& [pid, line] : child_processes())
        if (line.find(" --name victim ") != std::string::npos) ::kill(pid, SIGKILL);
      killed = true;
    }
  };
  const auto t0 = Clock::now();
  const LocalFarmResult r = render_local_farm(job.scene_text, job.scene_name, job.settings, o);
  REQUIRE(killed);
  CHECK(Clock::now() - t0 < std::chrono::seconds(30));
  CHECK(identical(r.rgb, in_process(job)));
  const auto& victim = worker_entry(r.record, "victim");
  CHECK(victim["state"] == "lost");
  CHECK(victim["tasks_lost"].get<int>() >= 1);
  CHECK(log.count("worker victim#") == 2);  // registered, then dropped
  CHECK(log.count("exited (killed by signal 9): lost") == 1);
}

TEST_CASE("farm: worker --lab runs the paper's 80 workstations as throttled workers of one process") {
  const FarmJob job = small_job(32, 96, 1);
  BrokerConfig cfg = test_broker_config(80);
  cfg.heartbeat_ms = 500;
  Broker broker(cfg, [](const std::string&) {});
  ChildProcess lab(test::rayfarm_exe(), {"worker", "--lab", test::source_dir() + "/configs/labs/paper-lab.json",
                                         "--connect", broker.endpoint(), "--threads", "1", "--heartbeat-ms", "500",
                                         "--quiet"});
  const FarmResult r = broker.run(job, deadline(60));
  broker.shutdown_workers();
  CHECK(identical(r.rgb, in_process(job)));
  REQUIRE(r.record["workers"].size() == 80);
  std::map<std::string, int> machines;
  for (const auto& w : r.record["workers"]) {
    const std::string name = w["name"];
    machines[name.substr(0, name.rfind('-'))] += 1;
    CHECK(w["throttle"].get<double>() * w["weight"].get<double>() == doctest::Approx(60.3).epsilon(0.001));
  }
  CHECK(machines == std::map<std::string, int>{
                        {"sun-ssc", 46}, {"sun-elc", 17}, {"sgi-indigo-r3000", 14}, {"sgi-indigo-r4000", 3}});
  CHECK(lab.wait_for(10));
}
