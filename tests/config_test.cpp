// Config and lab files from outside (protocol/config_file.h, worker/lab.h):
// regular files only, size-capped, every error naming the file and key.
#include <doctest/doctest.h>

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "broker/broker_config.h"
#include "tests/run_command.h"
#include "tests/test_files.h"
#include "tests/test_paths.h"
#include "tracer/error.h"
#include "worker/lab.h"
#include "worker/worker_config.h"

using namespace rayfarm;
namespace fs = std::filesystem;

namespace {

std::string error_of(const std::function<void()>& load) {
  try {
    load();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

// A command that must exit 1 at start (not 124, still retrying under its
// `timeout`) with a message holding `message`.
struct Refusal {
  std::string command;
  std::string message;
};

void check_refused(const std::vector<Refusal>& refusals) {
  for (const Refusal& r : refusals) {
    CAPTURE(r.command);
    const test::CommandResult run = test::run_command(r.command);
    CHECK(run.exit_code == 1);
    CHECK(run.output.find(r.message) != std::string::npos);
  }
}

}  // namespace

TEST_CASE("config: only regular files of at most 1 MiB are read") {
  const fs::path dir = test::scratch_dir("config-files");
  // A lab entry whose config is /dev/zero used to read until memory ran out.
  const std::string lab = test::write_file(dir / "lab.json", R"({"machines": [{"config": "/dev/zero", "count": 1}]})");
  CHECK(error_of([&] { load_lab(lab); }) ==
        lab + ": machines[0].config: /dev/zero: not a regular file");
  CHECK(error_of([&] { load_worker_config(dir.string()); }) == dir.string() + ": not a regular file");
  const std::string big = test::write_file(dir / "big.json", "{\"name\": \"" + std::string(2 << 20, 'x') + "\"}");
  CHECK(error_of([&] { load_worker_config(big); }) == big + ": larger than 1048576 bytes");
  fs::remove_all(dir);
}

TEST_CASE("config: a number JSON cannot hold names its file, line and column") {
  const fs::path dir = test::scratch_dir("config-overflow");
  const std::string lab =
      test::write_file(dir / "lab.json", R"({"machines": [{"weight": 21, "count": 2}, {"weight": 1e999, "count": 1}]})");
  CHECK(error_of([&] { load_lab(lab); }) == lab + ": invalid JSON: number out of range at line 1, column 54: 1e999 does not fit a double");
  const std::string broker =
      test::write_file(dir / "broker.json", R"({"heartbeat": {"interval_ms": 1000, "liveness": -1e400}})");
  CHECK(error_of([&] { load_broker_config(broker); }) ==
        broker + ": invalid JSON: number out of range at line 1, column 49: -1e400 does not fit a double");
  const std::string list = test::write_file(dir / "list.json", R"({"machines": [1, 2, 3e500]})");
  CHECK(error_of([&] { load_lab(list); }) == list + ": invalid JSON: number out of range at line 1, column 21: 3e500 does not fit a double");
  fs::remove_all(dir);
}

TEST_CASE("config: a key given twice in one object is refused, naming the file and key") {
  const fs::path dir = test::scratch_dir("config-duplicates");
  // The second weight used to win without a word.
  const std::string worker = test::write_file(dir / "worker.json", R"({"weight": 21, "credit": 2, "weight": 210})");
  CHECK(error_of([&] { load_worker_config(worker); }) == worker + ": invalid JSON: duplicate key \"weight\" in one object");
  const std::string broker =
      test::write_file(dir / "broker.json", R"({"heartbeat": {"interval_ms": 1000, "interval_ms": 10}})");
  CHECK(error_of([&] { load_broker_config(broker); }) ==
        broker + ": invalid JSON: duplicate key \"interval_ms\" in one object");
  // The same keys in sibling objects are no duplicates.
  const std::string lab =
      test::write_file(dir / "lab.json", R"({"machines": [{"weight": 21, "count": 2}, {"weight": 42, "count": 1}]})");
  CHECK(load_lab(lab).machine_count() == 3);
  fs::remove_all(dir);
}

TEST_CASE("config: lab sizes and reconnect ranges are checked") {
  const fs::path dir = test::scratch_dir("config-ranges");
  const std::string huge = test::write_file(dir / "huge.json", R"({"machines": [{"weight": 21, "count": 1048576}]})");
  CHECK(error_of([&] { load_lab(huge); }) == huge + ": machines[0].count: expected an integer in [1, 10000], found 1048576");
  // A whole number written with a point, or in quotes, is shown as written.
  const std::string point = test::write_file(dir / "point.json", R"({"machines": [{"weight": 21, "count": 2.0}]})");
  CHECK(error_of([&] { load_lab(point); }) == point + ": machines[0].count: expected an integer in [1, 10000], found 2.0");
  const std::string quoted = test::write_file(dir / "quoted.json", R"({"weight": "21"})");
  CHECK(error_of([&] { load_worker_config(quoted); }).find("weight: expected a number in [") != std::string::npos);
  CHECK(error_of([&] { load_worker_config(quoted); }).find("], found \"21\"") != std::string::npos);
  const std::string many = test::write_file(
      dir / "many.json", R"({"machines": [{"weight": 21, "count": 6000}, {"weight": 30, "count": 6000}]})");
  CHECK(error_of([&] { load_lab(many); }) ==
        many + ": machines[1].count: the lab would have 12000 machines, more than 10000");
  const std::string backoff =
      test::write_file(dir / "w.json", R"({"reconnect": {"initial_ms": 5000, "max_ms": 1000}})");
  CHECK(error_of([&] { load_worker_config(backoff); }) ==
        backoff + ": reconnect.initial_ms: must be <= reconnect.max_ms (5000 > 1000)");
  const std::string fine = test::write_file(dir / "ok.json", R"({"reconnect": {"initial_ms": 500, "max_ms": 500}})");
  CHECK(load_worker_config(fine).reconnect_max_ms == 500);
  fs::remove_all(dir);
}

TEST_CASE("config: a weight or throttle given NaN or infinity on the command line is refused, naming the option") {
  // CLI11's ranges let NaN through (every comparison with it is false): the
  // worker took its config's weight instead, silently.
  struct Case {
    const char* command;
    const char* message;
  } cases[] = {
      {" worker --connect tcp://127.0.0.1:1 --weight nan", "--weight: expected a finite number in [1e-06, 1e+06], found nan"},
      {" worker --connect tcp://127.0.0.1:1 --throttle inf", "--throttle: expected a finite number in [1, 1000], found inf"},
      {" broker --reference-weight nan", "--reference-weight: expected a finite number in [1e-06, 1e+06], found nan"},
  };
  for (const Case& c : cases) {
    CAPTURE(c.command);
    const test::CommandResult r = test::run_command("timeout 20 " + test::rayfarm_exe() + c.command);
    CHECK(r.exit_code != 0);
    CHECK(r.output.find(c.message) != std::string::npos);
  }
}

TEST_CASE("config: a worker name longer than the protocol allows is refused at start, not dropped by the broker") {
  // The broker drops a `ready` whose name is over 128 bytes: the worker never
  // registered and only heard "re-register", again and again.
  const test::CommandResult r = test::run_command("timeout 20 " + test::rayfarm_exe() +
                                                  " worker --connect tcp://127.0.0.1:1 --name " + std::string(129, 'n'));
  CHECK(r.exit_code == 1);
  CHECK(r.output.find("worker: a name of 129 bytes (--name, or \"name\" in its config or lab); the protocol allows at "
                      "most 128") != std::string::npos);
}

TEST_CASE("config: a worker name that is not UTF-8 is refused at start, naming --name") {
  // It died with "[json.exception.type_error.316] incomplete UTF-8 string" when it first spoke to the broker.
  const test::CommandResult r = test::run_command("timeout 20 " + test::rayfarm_exe() +
                                                  " worker --connect tcp://127.0.0.1:1 --name caf\xe9");
  CHECK(r.exit_code == 1);
  CHECK(r.output.find("worker: the name (--name, or \"name\" in its config or lab) is not valid UTF-8") !=
        std::string::npos);
  CHECK(r.output.find("json.exception") == std::string::npos);
}

TEST_CASE("config: a worker name with a control character is refused at start, naming the byte") {
  // A newline in it forged lines of the worker's own log.
  const test::CommandResult r = test::run_command("timeout 20 " + test::rayfarm_exe() +
                                                  " worker --connect tcp://127.0.0.1:1 --name \"$(printf 'w\\nx')\"");
  CHECK(r.exit_code == 1);
  CHECK(r.output.find("worker: the name (--name, or \"name\" in its config or lab) holds the control character 0x0a "
                      "at byte 2") != std::string::npos);
}

TEST_CASE("config: a key without its partner in a config file is named as the file says it, not as options") {
  const fs::path dir = test::scratch_dir("config-lone-keys");
  const std::string worker = test::write_file(dir / "worker.json", R"({"key": "w.key"})");
  const std::string broker = test::write_file(dir / "broker.json", R"({"key": "b.key"})");
  const std::string exe = "timeout 20 " + test::rayfarm_exe();
  test::CommandResult r = test::run_command(exe + " worker --config " + worker + " --connect tcp://127.0.0.1:1");
  CHECK(r.exit_code == 1);
  CHECK(r.output.find(worker + ": \"key\" needs \"broker_key\" (the broker's public key file) or --broker-key") !=
        std::string::npos);
  r = test::run_command(exe + " broker --config " + broker + " " + test::paper_scene("tetra") + " -o " +
                        (dir / "out.png").string());
  CHECK(r.exit_code == 1);
  CHECK(r.output.find(broker + ": \"key\" needs \"allow\" (the invited workers' *.pub files) or --allow DIR") !=
        std::string::npos);
  // Given on the command line, they are named as options still.
  r = test::run_command(exe + " worker --key " + (dir / "w.key").string() + " --connect tcp://127.0.0.1:1");
  CHECK(r.output.find("worker: --key and --broker-key go together") != std::string::npos);
  fs::remove_all(dir);
}

TEST_CASE("config: worker --help says that --liveness gives way to the broker's once it answers") {
  // A registered worker waits the broker's heartbeat x liveness (its `welcome`),
  // whatever --liveness says; the help said --liveness alone decided.
  const std::string help = test::run_command(test::rayfarm_exe() + " worker --help").output;
  CHECK(help.find("until a broker answers (then the broker's own)") != std::string::npos);
}

TEST_CASE("config: a broker endpoint ZeroMQ cannot use is named, and the worker exits") {
  const fs::path dir = test::scratch_dir("config-endpoint");
  const std::string config = test::write_file(dir / "w.json", R"({"weight": 21})");
  struct Case {
    const char* endpoint;
    const char* reason;
  } cases[] = {{"garbage://x", "a farm runs over TCP"}, {"tcp://no-port", "Invalid argument"}};
  for (const Case& c : cases) {
    CAPTURE(c.endpoint);
    // Bounded, should a worker ever retry such an endpoint instead of failing (exit 124).
    const test::CommandResult r = test::run_command("timeout 20 " + test::rayfarm_exe() + " worker --config " +
                                                    config + " --connect " + c.endpoint);
    CHECK(r.exit_code == 1);
    CHECK(r.output.find(std::string("cannot connect to the broker at '") + c.endpoint +
                        "' (--connect or \"connect\"): " + c.reason) != std::string::npos);
  }
  fs::remove_all(dir);
}

TEST_CASE("config: an endpoint port past 65535 or with trailing text is refused, not wrapped to another port") {
  // ZeroMQ read 112836 as port 47300 and "47302x" as 47302: the broker bound,
  // and the worker dialled, a port nobody had named. The ports that are valid
  // are any free one (the broker binds its worker socket before the announce
  // socket) or port 1, which nothing serves.
  const fs::path dir = test::scratch_dir("config-endpoint-port");
  const std::string exe = "timeout 10 " + test::rayfarm_exe();
  const std::string broker = exe + " broker " + test::paper_scene("tetra") + " -o " + (dir / "out.png").string() +
                             " --width 8 --spp 1 --no-progress";
  check_refused({
      {broker + " --bind tcp://127.0.0.1:112836 --announce tcp://127.0.0.1:*",
       "cannot bind the worker socket to 'tcp://127.0.0.1:112836': the port '112836' is no TCP port"},
      {broker + " --bind tcp://127.0.0.1:* --announce tcp://127.0.0.1:47302x",
       "cannot bind the announce socket to 'tcp://127.0.0.1:47302x': the port '47302x' is no TCP port"},
      {exe + " worker --connect tcp://127.0.0.1:112836",
       "cannot connect to the broker at 'tcp://127.0.0.1:112836' (--connect or \"connect\"): the port '112836' is no "
       "TCP port (expected 1..65535"},
      {exe + " worker --connect tcp://127.0.0.1:1 --subscribe tcp://127.0.0.1:112837",
       "cannot subscribe to the broker's announcements at 'tcp://127.0.0.1:112837' (--subscribe or \"subscribe\"): "
       "the port '112837' is no TCP port"},
  });
  fs::remove_all(dir);
}

TEST_CASE("config: a broker or worker given a transport other than tcp:// is refused at start naming it") {
  // A broker announcing on ipc:// stopped with "rayfarm: stoi" at the first
  // registration (the welcome names the announcements' port), and one taking
  // workers on ipc:// without keys refused them all as not loopback.
  const fs::path dir = test::scratch_dir("config-transport");
  const std::string exe = "timeout 10 " + test::rayfarm_exe();
  const std::string broker = exe + " broker " + test::paper_scene("tetra") + " -o " + (dir / "out.png").string() +
                             " --width 8 --spp 1 --no-progress";
  const std::string ipc = "ipc://" + (dir / "farm.sock").string();
  const std::string over_tcp = "a farm runs over TCP";
  check_refused({
      {broker + " --bind tcp://127.0.0.1:* --announce " + ipc,
       "cannot bind the announce socket to '" + ipc + "': " + over_tcp},
      {broker + " --bind " + ipc, "cannot bind the worker socket to '" + ipc + "': " + over_tcp},
      {exe + " worker --connect " + ipc,
       "cannot connect to the broker at '" + ipc + "' (--connect or \"connect\"): " + over_tcp},
  });
  fs::remove_all(dir);
}

TEST_CASE("config: a worker refuses at start a broker endpoint no broker can have: port 0 or *, inproc") {
  // Port 0 and inproc:// were dialled and retried forever, the worker saying
  // only "no broker answered"; port * failed as a bare "Invalid argument".
  const std::string exe = "timeout 10 " + test::rayfarm_exe() + " worker --threads 1";
  check_refused({
      {exe + " --connect tcp://127.0.0.1:0",
       "cannot connect to the broker at 'tcp://127.0.0.1:0' (--connect or \"connect\"): the port '0' means any free "
       "port to a bind, and no broker listens on it"},
      {exe + " --connect 'tcp://127.0.0.1:*'",
       "cannot connect to the broker at 'tcp://127.0.0.1:*' (--connect or \"connect\"): the port '*' means any free"},
      {exe + " --connect inproc://x",
       "cannot connect to the broker at 'inproc://x' (--connect or \"connect\"): inproc:// reaches only sockets "
       "inside one process, never a broker's; expected tcp://HOST:PORT"},
      {exe + " --connect tcp://127.0.0.1:1 --subscribe tcp://127.0.0.1:0",
       "cannot subscribe to the broker's announcements at 'tcp://127.0.0.1:0' (--subscribe or \"subscribe\"): the "
       "port '0' means any free"},
  });
}

TEST_CASE("config: a value of the wrong kind is quoted in the error, whatever kind was expected") {
  // Numbers were quoted ("found 0"), but a wrong boolean, string, object or
  // over-long name said only what was expected, not what the file held.
  const fs::path dir = test::scratch_dir("config-found-values");
  const std::string exe = "timeout 10 " + test::rayfarm_exe();
  struct Case {
    const char* role;
    const char* text;
    const char* message;
  } cases[] = {
      {"broker", R"({"progress": "yes"})", "progress: expected true or false, found \"yes\""},
      {"broker", R"({"bind": 5555})", "bind: expected a string, found 5555"},
      {"broker", R"({"heartbeat": [1000, 3]})", "heartbeat: expected a JSON object, found [1000,3]"},
      {"worker", R"({"max_isa": 2})", "max_isa: expected a string, found 2"},
      {"worker", R"({"reconnect": 1000})", "reconnect: expected a JSON object, found 1000"},
      {"worker", "[21]", "document: expected a JSON object, found [21]"},
  };
  for (const Case& c : cases) {
    CAPTURE(c.text);
    const std::string config = test::write_file(dir / "c.json", c.text);
    const std::string command =
        std::string(c.role) == "broker"
            ? " broker --config " + config + " " + test::paper_scene("tetra") + " -o " + (dir / "out.png").string() +
                  " --bind tcp://127.0.0.1:47304 --announce tcp://127.0.0.1:47305"
            : " worker --config " + config + " --connect tcp://127.0.0.1:47304";
    const test::CommandResult r = test::run_command(exe + command);
    CHECK(r.exit_code == 1);
    CHECK(r.output.find(config + ": " + c.message) != std::string::npos);
  }
  fs::remove_all(dir);
}

TEST_CASE("config: a string value quoted in an error is escaped once, as the file's name beside it is") {
  // The value was quoted with JSON's escapes and the message escaped again
  // where it is printed: an ESC read "a\\u001bb", a backslash "\\\\".
  const fs::path dir = test::scratch_dir("config-escape-once");
  const std::string config = test::write_file(dir / "w.json", R"({"weight": "a\u001bb\\c"})");
  const test::CommandResult r = test::run_command("timeout 10 " + test::rayfarm_exe() + " worker --config " + config +
                                                  " --connect tcp://127.0.0.1:47304");
  CHECK(r.exit_code == 1);
  CHECK(r.output == "rayfarm: --config " + config + ": weight: expected a number in [1e-06, 1e+06], found \"a\\x1bb\\\\c\"\n");
  fs::remove_all(dir);
}
