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
  CHECK(r.output.find("a lab of 300 machines needs about 4864 open files, but this process may open at most 256 "
                      "(RLIMIT_NOFILE hard limit") != std::string::npos);
  CHECK_THROWS_AS(reserve_files_for_workers(1u << 30), InputError);
  fs::remove_all(dir);
}
