// Many workers in one process (worker/lab_process.h): a lab larger than the
// old ZMQ_MAX_SOCKETS default of 1023 sockets (255 workers) registers whole,
// and one beyond the open-file limit fails at once with a message naming it.
#include <doctest/doctest.h>

#include <filesystem>

#include "tests/farm_peers.h"
#include "tests/run_command.h"
#include "tests/test_files.h"
#include "worker/lab_process.h"

using namespace rayfarm;
using namespace rayfarm::test;
namespace fs = std::filesystem;

namespace {

std::string lab_of(const fs::path& dir, int machines) {
  return write_file(dir / "lab.json", R"({"machines": [{"name": "m", "weight": 21, "count": )" +
                                          std::to_string(machines) + "}]}");
}

}  // namespace

TEST_CASE("lab process: 400 workers in one process all register") {
  const fs::path dir = scratch_dir("lab-400");
  BrokerConfig cfg = test_broker_config(0);
  cfg.heartbeat_ms = 1000;
  Broker broker(cfg, [](const std::string&) {});
  ChildProcess lab(rayfarm_exe(), {"worker", "--lab", lab_of(dir, 400), "--connect", broker.endpoint(), "--threads",
                                   "1", "--quiet"});
  const auto end = Clock::now() + std::chrono::seconds(60);
  while (broker.worker_count() < 400 && Clock::now() < end && lab.running()) broker.serve_for(0.2);
  CHECK(broker.worker_count() == 400);  // was 255 at most: "Too many open files" from ZeroMQ, then abort
  CHECK(lab.running());
  broker.shutdown_workers(0.5);
  CHECK(lab.wait_for(20));
  CHECK(lab.status() == 0);
  fs::remove_all(dir);
}

TEST_CASE("lab process: a lab beyond the open-file limit fails at once, naming the limit") {
  const fs::path dir = scratch_dir("lab-limit");
  const CommandResult r = run_command("ulimit -n 256 && " + rayfarm_exe() + " worker --lab " + lab_of(dir, 300) +
                                      " --connect tcp://127.0.0.1:9");
  CHECK(r.exit_code == 1);
  CHECK(r.output.find("a lab of 300 machines needs about 6064 open files, but this process may open at most 256 "
                      "(RLIMIT_NOFILE hard limit") != std::string::npos);
  CHECK_THROWS_AS(reserve_files_for_workers(1u << 30), InputError);
  fs::remove_all(dir);
}

TEST_CASE("lab process: 200 workers that lose the broker at once reconnect, all of them") {
  // A silent broker makes every lab worker reconnect in the same instant
  // (here some 1,200 reconnects), and each opens its new sockets before
  // libzmq has reaped its old ones. With room for only one set per worker,
  // 205 of 2,000 workers in 8 processes on 2 cores stopped with "Too many
  // open files"; on an idle machine the reaper keeps up, so this passes there
  // either way and guards the reconnect path itself.
  const fs::path dir = scratch_dir("lab-reconnect");
  write_file(dir / "fast.json",
             R"({"weight": 21, "heartbeat": {"interval_ms": 100, "liveness": 2}, "reconnect": {"initial_ms": 10, "max_ms": 20}})");
  const std::string lab_file = write_file(dir / "lab.json", R"({"machines": [{"config": "fast.json", "count": 200}]})");
  BrokerConfig cfg = test_broker_config(0);
  cfg.heartbeat_ms = 100;
  cfg.liveness = 3;  // workers adopt it: 300 ms of silence and they reconnect
  Broker broker(cfg, [](const std::string&) {});
  ChildProcess lab(rayfarm_exe(), {"worker", "--lab", lab_file, "--connect", broker.endpoint(), "--threads", "1", "--quiet"});
  // Serves until exactly the 200 workers are registered: a worker slow to
  // start (a sanitizer build) may give up on its first registration and
  // register again, and the broker counts the lost one until it drops it
  // after 300 ms of silence.
  auto serve_until_all_registered = [&] {
    const auto end = Clock::now() + std::chrono::seconds(60);
    do broker.serve_for(0.2);
    while (broker.worker_count() != 200 && Clock::now() < end && lab.running());
    return broker.worker_count();
  };
  REQUIRE(serve_until_all_registered() == 200);
  for (int silence = 0; silence < 3; ++silence) {  // each silence: every worker reconnects, some more than once
    std::this_thread::sleep_for(std::chrono::milliseconds(600));
    broker.serve_for(1.0);  // they register again
  }
  // Every one back, so that each gets the shutdown below.
  CHECK(serve_until_all_registered() == 200);
  CHECK(lab.running());
  broker.shutdown_workers(0.5);
  CHECK(lab.wait_for(20));
  CHECK(describe_status(lab.status()) == "exit code 0");  // 1 if any worker thread stopped
  fs::remove_all(dir);
}

TEST_CASE("lab process: a machine that stops says why escaped, as every worker log line is") {
  // The lab printed the error as it was: an ESC in its --connect reached the terminal.
  const fs::path dir = scratch_dir("lab-stopped-escaped");
  const CommandResult r = run_command("timeout 20 " + rayfarm_exe() + " worker --lab " + lab_of(dir, 1) +
                                      " --connect \"$(printf 'tcp://a\\033b:1')\"");
  CHECK(r.exit_code == 1);
  CHECK(r.output.find("rayfarm worker m-01: stopped: cannot connect to the broker at 'tcp://a\\x1bb:1' (--connect or "
                      "\"connect\"): Invalid argument") != std::string::npos);
  CHECK(r.output.find('\x1b') == std::string::npos);
  fs::remove_all(dir);
}
