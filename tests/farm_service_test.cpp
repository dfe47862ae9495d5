// The service end to end: a real `rayfarm broker --serve` process, real
// `rayfarm worker` processes, the real client commands, HTTP on 127.0.0.1 port
// 0 and ZeroMQ on ephemeral ports (read back from DIR/service.json), real kill
// -9. Every image is compared byte for byte with `rayfarm render` in-process.
// Throttled workers make a job slow enough to kill half way.
#include <doctest/doctest.h>

#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <memory>
#include <sstream>
#include <thread>
#include <utility>

#include <httplib.h>

#include "broker/child_process.h"
#include "service/api_client.h"
#include "tests/http_peers.h"
#include "tests/run_command.h"
#include "tests/service_scenes.h"
#include "tests/test_files.h"
#include "tests/test_paths.h"
#include "tracer/text_file.h"

using namespace rayfarm;
namespace fs = std::filesystem;
using nlohmann::json;
using Clock = std::chrono::steady_clock;

namespace {

std::string fresh_dir(const std::string& name) {
  const fs::path dir = test::process_dir("serve-test") / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir.string();
}

std::string port_of(const std::string& endpoint) { return endpoint.substr(endpoint.rfind(':') + 1); }

// Polls `done` every 20 ms for up to `seconds`.
template <class Fn> bool eventually(double seconds, Fn done) {
  const auto end = Clock::now() + std::chrono::duration<double>(seconds);
  while (Clock::now() < end) {
    if (done()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return done();
}

// A broker service process and its workers.
struct Farm {
  std::string dir;
  std::unique_ptr<ChildProcess> broker;
  std::vector<std::unique_ptr<ChildProcess>> workers;
  json where;  // DIR/service.json: http, workers, announce
  size_t memory_limit_kib = 0;  // > 0: the broker runs under `ulimit -v`, as on a head node short of memory
  std::string log_file;         // non-empty: the broker's log is appended here, for the test to read
  std::string ignored;          // signals it starts with ignored, as `trap` names them ("HUP" is nohup's)

  explicit Farm(std::string state) : dir(std::move(state)) {}

  // `http_port`/`worker_port` "0"/"*": any; a restart passes the old ones so
  // clients and workers find it again.
  void start_broker(const std::string& http_port = "0", const std::string& worker_port = "*",
                    const std::vector<std::string>& more = {}) {
    fs::remove(dir + "/service.json");
    std::vector<std::string> args{"broker", "--serve", "--state", dir, "--http", "127.0.0.1:" + http_port, "--bind",
                                  "tcp://127.0.0.1:" + worker_port, "--announce", "tcp://127.0.0.1:*", "--no-progress",
                                  "--heartbeat-ms", "200", "--base-rows", "2"};
    args.insert(args.end(), more.begin(), more.end());
    if (memory_limit_kib == 0 && log_file.empty() && ignored.empty()) {
      broker = std::make_unique<ChildProcess>(test::rayfarm_exe(), args);
    } else {
      const std::string limit = memory_limit_kib ? "ulimit -v " + std::to_string(memory_limit_kib) + " && " : "";
      const std::string nohup = ignored.empty() ? "" : "trap '' " + ignored + " && ";
      const std::string log = log_file.empty() ? "" : " 2>>\"" + log_file + "\"";
      args.insert(args.begin(), {"-c", limit + nohup + "exec \"$@\"" + log, "sh", test::rayfarm_exe()});
      broker = std::make_unique<ChildProcess>("/bin/sh", args);
    }
    REQUIRE(eventually(15, [&] { return fs::exists(dir + "/service.json"); }));
    where = read_json_file(dir + "/service.json");
  }

  void start_worker(double throttle) {
    workers.push_back(std::make_unique<ChildProcess>(
        test::rayfarm_exe(),
        std::vector<std::string>{"worker", "--connect", where["workers"].get<std::string>(), "--threads", "1",
                                 "--throttle", std::to_string(throttle), "--heartbeat-ms", "200", "--quiet",
                                 "--name", "w" + std::to_string(workers.size() + 1)}));
  }

  std::string url() const { return where["http"].get<std::string>(); }
  std::string cli(const std::string& args) const { return test::rayfarm_exe() + " " + args + " --broker " + url(); }
};

// Writes frame `i` of the test animation and its in-process render.
std::string scene_file(const std::string& dir, int i, int width = 48, int height = 32) {
  const std::string path = dir + "/frame" + std::to_string(i) + ".nff";
  write_text_file(path, test::tiny_scene(i, width, height));
  return path;
}

// The SPD balls scene at 64x64: ~1 ms a row, so throttled workers take seconds.
std::string balls() { return test::source_dir() + "/scenes/balls.nff --width 64"; }

std::string reference_render(const std::string& scene, const std::string& out) {
  const auto r = test::run_command(test::rayfarm_exe() + " render " + scene + " -o " + out + " --spp 4 --threads 1");
  REQUIRE_MESSAGE(r.exit_code == 0, r.output);
  return read_text_file(out);
}

uint64_t submit(const Farm& farm, const std::string& args) {
  // In a subshell: run_command() appends its own 2>&1, which a 2>/dev/null
  // beside it left the last word to.
  const auto r = test::run_command("(" + farm.cli("submit " + args + " --spp 4") + " 2>/dev/null)");
  REQUIRE_MESSAGE(r.exit_code == 0, r.output);
  CHECK(r.output.find_first_not_of("0123456789\n") == std::string::npos);  // the id alone
  return std::stoull(r.output);
}

// A client sending a job's body of 64 MiB at some 1.3 MB/s, well above the
// least rate the service waits for (http_connection.h), for up to ~50 s: a
// service stopped meanwhile waits for the body before it exits, as for a
// large scene on a slow link.
struct SlowUpload {
  static constexpr size_t kBytes = size_t(64) << 20;
  int fd = -1;
  std::atomic<bool> done{false};
  std::thread sending;

  explicit SlowUpload(const std::string& url) {
    fd = http_test::send_raw(std::stoi(port_of(url)),
                             "POST /api/jobs HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
                             "Expect: 100-continue\r\nContent-Length: " +
                                 std::to_string(kBytes) + "\r\n\r\n");
    // Told to go on once a server thread holds the request: a stop now waits for it.
    std::string answer;
    REQUIRE(eventually(10, [&] {
      pollfd p{fd, POLLIN, 0};
      char buf[256];
      const ssize_t n = ::poll(&p, 1, 0) == 1 ? ::recv(fd, buf, sizeof buf, 0) : 0;
      if (n > 0) answer.append(buf, static_cast<size_t>(n));
      return answer.find("100 Continue") != std::string::npos;
    }));
    sending = std::thread([this] {
      const std::string chunk(64 << 10, ' ');
      for (size_t sent = 0; !done && sent + chunk.size() < kBytes; sent += chunk.size()) {
        if (::send(fd, chunk.data(), chunk.size(), MSG_NOSIGNAL) != static_cast<ssize_t>(chunk.size())) return;
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
      }
    });
  }
  // Stops sending and closes the connection: the service reads the body's end.
  void finish() {
    done = true;
    if (sending.joinable()) sending.join();
    if (fd >= 0) ::close(fd);
    fd = -1;
  }
  ~SlowUpload() { finish(); }
};

}  // namespace

TEST_CASE("service: queued jobs and a three-frame job match in-process renders, bad input never disturbs a job" *
          doctest::timeout(120)) {
  const std::string dir = fresh_dir("queue");
  Farm farm(dir + "/state");
  farm.start_broker();
  farm.start_worker(50);
  farm.start_worker(50);

  const std::string still = balls();
  const uint64_t one = submit(farm, still);
  const uint64_t anim = submit(farm, scene_file(dir, 0) + " " + scene_file(dir, 1) + " " + scene_file(dir, 2));
  CHECK(anim == one + 1);

  // While the first job runs: a malformed submission gets a reason, the job goes on.
  ApiClient api(farm.url());
  REQUIRE(eventually(30, [&] { return api.status(one)["state"] == "running"; }));
  Submission bad;
  bad.scenes.push_back({"broken.nff", "v\nfrom 0 0 5\nat 0 0 0\nup 0 1 0\nangle 45\nhither 1\nresolution 8 8\ns 0 0\n"});
  try {
    api.submit(bad);
    FAIL("a broken scene was accepted");
  } catch (const ApiError& e) {
    CHECK(e.status == 400);
    CHECK(std::string(e.what()).find("broken.nff:8") != std::string::npos);
  }
  const auto garbage = test::run_command("curl -s -X POST --data-binary '{\"scenes\": 3}' " + farm.url() + "/api/jobs");
  if (garbage.exit_code == 0) CHECK(garbage.output.find("\"error\"") != std::string::npos);

  const auto fetched = test::run_command(farm.cli("fetch " + std::to_string(anim) + " -o " + dir + "/anim.png --wait"));
  REQUIRE_MESSAGE(fetched.exit_code == 0, fetched.output);
  REQUIRE(test::run_command(farm.cli("fetch " + std::to_string(one) + " -o " + dir + "/still.png")).exit_code == 0);
  CHECK(read_text_file(dir + "/still.png") == reference_render(still, dir + "/still-ref.png"));
  for (int i = 0; i < 3; ++i) {
    CAPTURE(i);
    const std::string out = dir + "/anim-000" + std::to_string(i + 1) + ".png";
    CHECK(read_text_file(out) == reference_render(dir + "/frame" + std::to_string(i) + ".nff", out + ".ref.png"));
  }
  const json s = api.status(anim);
  CHECK(s["state"] == "done");
  CHECK(s["frames_done"] == 3);
  CHECK(s["rows_done"] == s["rows_total"]);
  CHECK(s["resumed_rows"] == 0);
  CHECK(api.status(one)["state"] == "done");
  const auto status = test::run_command(farm.cli("status " + std::to_string(anim) + " --json"));
  CHECK(json::parse(status.output)["state"] == "done");
}

TEST_CASE("service: a cancelled job stops and the next one runs" * doctest::timeout(120)) {
  const std::string dir = fresh_dir("cancel");
  Farm farm(dir + "/state");
  farm.start_broker();
  farm.start_worker(200);
  const uint64_t slow = submit(farm, balls());
  const std::string quick_scene = scene_file(dir, 1, 16, 8);
  ApiClient api(farm.url());
  REQUIRE(eventually(30, [&] { return api.status(slow)["rows_done"].get<int>() > 0; }));
  const auto r = test::run_command(farm.cli("cancel " + std::to_string(slow)));
  REQUIRE_MESSAGE(r.exit_code == 0, r.output);
  CHECK(r.output.find("cancelled") != std::string::npos);
  const json s = api.status(slow);
  CHECK(s["state"] == "cancelled");
  CHECK(s["rows_done"].get<int>() < s["rows_total"].get<int>());
  const auto again = test::run_command(farm.cli("cancel " + std::to_string(slow)));
  CHECK(again.exit_code != 0);
  CHECK(again.output.find("already cancelled") != std::string::npos);
  CHECK(test::run_command(farm.cli("fetch " + std::to_string(slow) + " -o " + dir + "/x.png")).exit_code != 0);

  const uint64_t quick = submit(farm, quick_scene);
  REQUIRE(test::run_command(farm.cli("fetch " + std::to_string(quick) + " -o " + dir + "/q.png --wait")).exit_code == 0);
  CHECK(read_text_file(dir + "/q.png") == reference_render(quick_scene, dir + "/q-ref.png"));
}

TEST_CASE("service: kill -9 half way, torn journal, restart: rows kept, image identical" *
          doctest::timeout(180)) {
  const std::string dir = fresh_dir("kill");
  Farm farm(dir + "/state");
  farm.start_broker();
  farm.start_worker(120);
  farm.start_worker(120);
  const std::string scene = balls();
  const uint64_t job = submit(farm, scene);
  const std::string http_port = port_of(farm.url()), worker_port = port_of(farm.where["workers"]);
  // A client waiting for the image, started before the crash: it must ride it out.
  ChildProcess waiter(test::rayfarm_exe(), {"fetch", std::to_string(job), "-o", dir + "/out.png", "--wait",
                                            "--broker", farm.url()});
  ApiClient api(farm.url());
  int before = 0;
  REQUIRE(eventually(60, [&] {
    before = api.status(job)["rows_done"].get<int>();
    return before >= 32;
  }));
  farm.broker->kill(SIGKILL);
  REQUIRE(farm.broker->wait_for(5));
  before = std::max(before, 0);
  // The crash tore the last record: cut 5 bytes off the journal's end.
  const std::string journal = dir + "/state/jobs/" + std::to_string(job) + "/rows.journal";
  REQUIRE(fs::exists(journal));
  const auto journal_size = fs::file_size(journal);
  fs::resize_file(journal, journal_size - 5);

  farm.start_broker(http_port, worker_port);
  REQUIRE(waiter.wait_for(120));
  CHECK(waiter.status() == 0);
  CHECK(read_text_file(dir + "/out.png") == reference_render(scene, dir + "/ref.png"));
  const json s = api.status(job);
  CHECK(s["state"] == "done");
  // Every row journaled before the kill came back, but the torn one (a task of
  // at most 2 rows): rows_done was read before the kill, so more may have been kept.
  CHECK(s["resumed_rows"].get<int>() >= before - 2);
  CHECK(s["resumed_rows"].get<int>() < 64);
  MESSAGE("rows done at kill ", before, ", resumed ", s["resumed_rows"].get<int>(), ", re-rendered ",
          s["rerendered_rows"].get<int>());
  const json record = read_json_file(dir + "/state/jobs/" + std::to_string(job) + "/record-0001.json");
  CHECK(record["resumed_rows"] == s["resumed_rows"]);
  CHECK(!fs::exists(journal));  // a finished job needs no journal
}

TEST_CASE("service: a stop on SIGTERM or SIGINT logs the signal and what the next start resumes, not nothing" *
          doctest::timeout(120)) {
  const std::string dir = fresh_dir("signal-stop"), log = dir + "/broker.log";
  Farm farm(dir + "/state");
  farm.log_file = log;
  farm.start_broker();
  farm.start_worker(120);
  const uint64_t job = submit(farm, balls());
  const uint64_t queued = submit(farm, scene_file(dir, 0));
  ApiClient api(farm.url());
  REQUIRE(eventually(60, [&] { return api.status(job)["rows_done"].get<int>() >= 4; }));
  const auto stop = [&](int signal) {
    farm.broker->kill(signal);
    REQUIRE(farm.broker->wait_for(5));
    CHECK(farm.broker->status() == 0);  // a deliberate stop, as before
    const std::string text = read_text_file(log);
    const size_t said = text.rfind("rayfarm broker: stopping on ");
    REQUIRE_MESSAGE(said != std::string::npos, text);
    return text.substr(said);
  };
  const std::string prefix =
      "rayfarm broker: stopping on SIGTERM: job " + std::to_string(job) + " frame 1/1 resumes with ";
  const std::string said = stop(SIGTERM);
  REQUIRE_MESSAGE(said.rfind(prefix, 0) == 0, said);
  const int journaled = std::stoi(said.substr(prefix.size()));
  CHECK(said == prefix + std::to_string(journaled) + " of 64 rows journaled; 1 job(s) queued\n");
  CHECK(journaled >= 4);

  // The next start resumes exactly the rows the line named.
  farm.start_broker();
  ApiClient restarted(farm.url());
  CHECK(restarted.status(job)["resumed_rows"] == journaled);
  CHECK(stop(SIGINT) == "rayfarm broker: stopping on SIGINT: job " + std::to_string(job) + " frame 1/1 resumes with " +
                            std::to_string(journaled) + " of 64 rows journaled; 1 job(s) queued\n");

  farm.start_broker();
  ApiClient idle(farm.url());
  idle.cancel(job);
  idle.cancel(queued);
  CHECK(stop(SIGTERM) == "rayfarm broker: stopping on SIGTERM: no job running, no job queued\n");
}

TEST_CASE("service: a closed terminal (SIGHUP) stops it as SIGTERM does, with the line and the journal, unless"
          " it started under nohup, or as a background job with SIGINT ignored" * doctest::timeout(120)) {
  const std::string dir = fresh_dir("hangup-stop"), log = dir + "/broker.log";
  Farm farm(dir + "/state");
  farm.log_file = log;
  farm.start_broker();
  farm.start_worker(120);
  const uint64_t job = submit(farm, balls());
  ApiClient api(farm.url());
  REQUIRE(eventually(60, [&] { return api.status(job)["rows_done"].get<int>() >= 4; }));
  // It died of the signal, silently: no line, and a parent saw "killed by signal 1".
  farm.broker->kill(SIGHUP);
  REQUIRE(farm.broker->wait_for(5));
  CHECK(farm.broker->status() == 0);
  const std::string text = read_text_file(log);
  const std::string prefix =
      "rayfarm broker: stopping on SIGHUP: job " + std::to_string(job) + " frame 1/1 resumes with ";
  const size_t at = text.rfind(prefix);
  REQUIRE_MESSAGE(at != std::string::npos, text);
  const int journaled = std::stoi(text.substr(at + prefix.size()));
  CHECK(text.substr(at) == prefix + std::to_string(journaled) + " of 64 rows journaled; no job queued\n");
  CHECK(journaled >= 4);

  // Under nohup the hangup is not its to heed, nor, as a script's background
  // job, the Ctrl-C meant for the script (a worker's rule too): it keeps
  // serving, and resumes exactly the rows the line named.
  farm.ignored = "HUP INT";
  farm.start_broker();
  ApiClient kept(farm.url());
  CHECK(kept.status(job)["resumed_rows"] == journaled);
  farm.broker->kill(SIGHUP);
  farm.broker->kill(SIGINT);
  CHECK_FALSE(farm.broker->wait_for(1));
  CHECK(kept.status(job)["resumed_rows"] == journaled);
  farm.broker->kill(SIGTERM);
  REQUIRE(farm.broker->wait_for(5));
  CHECK(farm.broker->status() == 0);
  CHECK(read_text_file(log).find("rayfarm broker: stopping on SIGTERM: ") != std::string::npos);
}

TEST_CASE("service: a start waiting for a state folder another broker holds stops on SIGTERM, SIGINT or SIGHUP"
          " with a line, not killed by it, and leaves that broker serving" * doctest::timeout(60)) {
  const std::string dir = fresh_dir("lock-wait-stop"), log = dir + "/second.log";
  Farm first(dir + "/state");
  first.start_broker();
  const std::string where = read_text_file(dir + "/state/service.json");
  for (const int signal : {SIGTERM, SIGINT, SIGHUP}) {
    const std::string name = signal == SIGTERM ? "SIGTERM" : signal == SIGINT ? "SIGINT" : "SIGHUP";
    CAPTURE(name);
    fs::remove(log);
    ChildProcess second("/bin/sh", {"-c", "exec \"$@\" 2>>\"" + log + "\"", "sh", test::rayfarm_exe(), "broker",
                                    "--serve", "--state", dir + "/state", "--http", "127.0.0.1:0", "--bind",
                                    "tcp://127.0.0.1:*", "--announce", "tcp://127.0.0.1:*", "--no-progress"});
    // The lock is waited for 2 s before the folder is refused: the signal comes within them.
    REQUIRE(eventually(10, [&] {
      return fs::exists(log) && read_text_file(log).find("locked by another broker; waiting") != std::string::npos;
    }));
    second.kill(signal);
    REQUIRE(second.wait_for(5));
    // It died of the signal, silently: status 15 (2, 1) and no line.
    CHECK(second.status() == 0);  // a deliberate stop, as of a serving broker
    const std::string text = read_text_file(log);
    CHECK_MESSAGE(text.find("rayfarm broker: stopping on " + name + " while waiting for " + dir +
                            "/state, locked by another broker; the folder was not taken\n") != std::string::npos,
                  text);
  }
  CHECK(first.broker->running());
  CHECK(read_text_file(dir + "/state/service.json") == where);
  CHECK(ApiClient(first.url()).list().empty());
}

TEST_CASE("service: a second SIGTERM while a stop waits for a request ends it at once, said on stderr, one alone waits"
          * doctest::timeout(120)) {
  const std::string dir = fresh_dir("second-signal"), log = dir + "/broker.log";
  Farm farm(dir + "/state");
  farm.log_file = log;
  const auto said_stopping = [&] {
    return eventually(30, [&] { return read_text_file(log).find("rayfarm broker: stopping on SIGTERM") != std::string::npos; });
  };
  // One signal: the clean stop, which waits for the upload under way.
  farm.start_broker();
  {
    SlowUpload upload(farm.url());
    farm.broker->kill(SIGTERM);
    REQUIRE(said_stopping());
    CHECK(farm.broker->running());  // the body still arrives
    upload.finish();
    REQUIRE(farm.broker->wait_for(30));
    CHECK(describe_status(farm.broker->status()) == "exit code 0");
    CHECK(read_text_file(log).find("rayfarm: second") == std::string::npos);
  }
  // A second one meanwhile: no more waiting. It dies of the signal (143 in a
  // shell), as a service killed outright; the next start opens the folder.
  fs::remove(log);
  farm.start_broker();
  {
    SlowUpload upload(farm.url());
    farm.broker->kill(SIGTERM);
    REQUIRE(said_stopping());
    farm.broker->kill(SIGTERM);
    REQUIRE(farm.broker->wait_for(30));
    CHECK(describe_status(farm.broker->status()) == "killed by signal " + std::to_string(SIGTERM));
    const std::string text = read_text_file(log);
    CHECK_MESSAGE(text.find("rayfarm: second SIGTERM: stopping now\n") != std::string::npos, text);
  }
  farm.start_broker();
  CHECK(ApiClient(farm.url()).list().empty());
}

TEST_CASE("service: /api/service names the worker socket the broker bound, for the status page's hint" *
          doctest::timeout(60)) {
  Farm farm(fresh_dir("service-endpoint") + "/state");
  farm.start_broker();
  httplib::Client client(farm.url());
  const auto r = client.Get("/api/service");
  REQUIRE(r);
  CHECK(r->status == 200);
  // Bound to 127.0.0.1 on an ephemeral port: workers connect to that very address.
  CHECK(json::parse(r->body) == json{{"workers", farm.where["workers"]},
                                     {"worker_connect", farm.where["workers"]},
                                     {"worker_command", "rayfarm worker --connect " + farm.where["workers"].get<std::string>()},
                                     {"allow", nullptr}});
}

TEST_CASE("service: on a keyed farm the worker hint names the key options, and the command it suggests is admitted"
          " once its WORKER.key is filled in" * doctest::timeout(60)) {
  // The hint said `rayfarm worker --connect ADDRESS` alone: a worker started
  // so was never admitted by a broker with --key/--allow.
  const std::string dir = fresh_dir("keyed-hint"), keys = dir + "/keys";
  fs::create_directories(keys + "/allow");
  REQUIRE(test::run_command(test::rayfarm_exe() + " keygen -o " + keys + "/broker").exit_code == 0);
  REQUIRE(test::run_command(test::rayfarm_exe() + " keygen -o " + keys + "/allow/w1").exit_code == 0);
  Farm farm(dir + "/state");
  // Given as paths from where the broker runs, named from the root: the page is read elsewhere.
  const std::string cwd = fs::current_path().string();
  farm.start_broker("0", "*", {"--key", fs::relative(keys + "/broker.key", cwd).string(), "--allow",
                               fs::relative(keys + "/allow", cwd).string()});
  httplib::Client client(farm.url());
  const auto r = client.Get("/api/service");
  REQUIRE(r);
  REQUIRE(r->status == 200);
  const json service = json::parse(r->body);
  const std::string command = service["worker_command"];
  CHECK(command == "rayfarm worker --connect " + farm.where["workers"].get<std::string>() +
                       " --key WORKER.key --broker-key " + keys + "/broker.pub");
  CHECK(service["allow"] == keys + "/allow");
  // The secret key is never named, nor its contents given.
  CHECK(r->body.find("broker.key") == std::string::npos);
  const std::string secret = read_text_file(keys + "/broker.key");
  const std::string z85 = secret.substr(secret.rfind('\n', secret.size() - 2) + 1, 40);  // its last line
  REQUIRE(z85.size() == 40);
  CHECK(r->body.find(z85) == std::string::npos);

  // The suggested command, its placeholder filled in, is admitted.
  const std::string filled = command.substr(std::string("rayfarm ").size());
  std::vector<std::string> args;
  std::istringstream words(filled.substr(0, filled.find("WORKER.key")) + keys + "/allow/w1.key" +
                           filled.substr(filled.find("WORKER.key") + std::string("WORKER.key").size()));
  for (std::string w; words >> w;) args.push_back(w);
  for (const char* more : {"--threads", "1", "--heartbeat-ms", "200", "--quiet"}) args.emplace_back(more);
  ChildProcess worker(test::rayfarm_exe(), args);
  CHECK(eventually(20, [&] {
    const auto workers = client.Get("/api/workers");
    return workers && workers->status == 200 && json::parse(workers->body).size() == 1;
  }));
}

TEST_CASE("service: a frame the state folder cannot take stops the service with its rows journaled, and a"
          " restart finishes the job, not failing it" * doctest::timeout(120)) {
  const std::string dir = fresh_dir("unwritable-frame"), log = dir + "/broker.log";
  Farm farm(dir + "/state");
  farm.log_file = log;
  farm.start_broker();
  const std::string http_port = port_of(farm.url()), worker_port = port_of(farm.where["workers"]);
  const std::string scene = scene_file(dir, 0);
  const uint64_t job = submit(farm, scene);
  const std::string job_dir = farm.dir + "/jobs/" + std::to_string(job);
  // A folder where the frame goes: its rename fails as on a full disk, while
  // the journal still takes rows.
  fs::create_directories(job_dir + "/frame-0001.rgbf/x");
  farm.start_worker(1);
  REQUIRE(farm.broker->wait_for(30));
  CHECK(farm.broker->status() != 0);
  CHECK(read_text_file(log).find("job " + std::to_string(job) +
                                 " frame 1 cannot be saved; the service stops, its rows stay journaled for the next "
                                 "start: the state folder: " + job_dir + "/frame-0001.rgbf: cannot write") !=
        std::string::npos);
  CHECK(read_json_file(job_dir + "/status.json")["state"] == "running");
  CHECK(fs::file_size(job_dir + "/rows.journal") > 32 * 48 * 12);  // every row

  fs::remove_all(job_dir + "/frame-0001.rgbf");
  farm.start_broker(http_port, worker_port);  // where the worker waits
  const auto fetched = test::run_command(farm.cli("fetch " + std::to_string(job) + " -o " + dir + "/out.png --wait"));
  REQUIRE_MESSAGE(fetched.exit_code == 0, fetched.output);
  CHECK(read_text_file(dir + "/out.png") == reference_render(scene, dir + "/ref.png"));
  const json s = ApiClient(farm.url()).status(job);
  CHECK(s["state"] == "done");
  CHECK(s["resumed_rows"] == 32);
}

TEST_CASE("service: a submission or cancel the state folder cannot take is answered 500 naming the file, not 400"
          " bad input" * doctest::timeout(60)) {
  const std::string dir = fresh_dir("unwritable-submission");
  Farm farm(dir + "/state");
  farm.start_broker();
  ApiClient api(farm.url());
  Submission s;
  s.scenes.push_back({"a.nff", test::tiny_scene(0)});
  const uint64_t job = api.submit(s);
  // Started (its status saved) even with no worker: damaged before that, the
  // status.json the start rewrites raced the test, or the start's failed save
  // stopped the service under the requests below.
  REQUIRE(eventually(30, [&] { return api.status(job)["state"] == "running"; }));
  // Folders where the highest id given out and the job's status go: their
  // renames fail as on a full disk.
  fs::remove(farm.dir + "/last-id");
  fs::create_directories(farm.dir + "/last-id/x");
  fs::remove(farm.dir + "/jobs/" + std::to_string(job) + "/status.json");
  fs::create_directories(farm.dir + "/jobs/" + std::to_string(job) + "/status.json/x");
  const auto answer_to = [](auto request) {
    try {
      request();
    } catch (const ApiError& e) {
      return std::to_string(e.status) + " " + e.what();
    }
    return std::string("accepted");
  };
  const std::string submitted = answer_to([&] { api.submit(s); });
  CHECK_MESSAGE(submitted.rfind("500 ", 0) == 0, submitted);
  CHECK_MESSAGE(submitted.find("the state folder: " + farm.dir + "/last-id: cannot write") != std::string::npos,
                submitted);
  const std::string cancelled = answer_to([&] { api.cancel(job); });
  CHECK_MESSAGE(cancelled.rfind("500 ", 0) == 0, cancelled);
  CHECK_MESSAGE(cancelled.find("the state folder: " + farm.dir + "/jobs/" + std::to_string(job) +
                               "/status.json: cannot write") != std::string::npos,
                cancelled);
  CHECK(farm.broker->running());
}

TEST_CASE("service: a job folder whose status.json was lost is set aside whole and named in the log, not dropped"
          " silently" * doctest::timeout(120)) {
  const std::string dir = fresh_dir("lost-status"), log = dir + "/broker.log";
  Farm farm(dir + "/state");
  farm.log_file = log;
  farm.start_broker();
  farm.start_worker(1);
  const std::string scene = scene_file(dir, 0);
  const uint64_t job = submit(farm, scene);
  const std::string id = std::to_string(job);
  REQUIRE(test::run_command(farm.cli("fetch " + id + " -o " + dir + "/out.png --wait")).exit_code == 0);
  farm.broker->kill(SIGKILL);
  REQUIRE(farm.broker->wait_for(5));
  const std::string job_dir = farm.dir + "/jobs/" + id, damaged = farm.dir + "/damaged/" + id;
  fs::remove(job_dir + "/status.json");

  farm.start_broker();
  CHECK(read_text_file(log).find(job_dir +
                                 ": cannot restore the job: status.json: missing, though the folder holds "
                                 "frame-0001.rgbf, record-0001.json; moved whole to " + damaged +
                                 ", the other jobs go on") != std::string::npos);
  CHECK(fs::exists(damaged + "/frame-0001.rgbf"));
  CHECK(!fs::exists(job_dir));
  CHECK(submit(farm, scene) == job + 1);  // its id is not given again
}

TEST_CASE("service: the jobs' log lines are escaped once, as the broker's are" * doctest::timeout(60)) {
  // A backslash in DIR came out as four in "cannot restore the job" (escaped
  // by the jobs, then again on the way to the log), two in "state in DIR".
  const std::string dir = fresh_dir("escaped-once"), log = dir + "/broker.log";
  Farm farm(dir + "/state\\x");
  farm.log_file = log;
  const std::string job_dir = farm.dir + "/jobs/9";
  fs::create_directories(job_dir);
  write_text_file(farm.dir + "/rayfarm-state.json", R"({"format": "rayfarm-state", "version": 1})");
  write_text_file(job_dir + "/frame-0001.rgbf", "frame");  // no status.json: set aside
  farm.start_broker();
  const std::string escaped = dir + "/state\\\\x";
  CHECK(eventually(10, [&] { return read_text_file(log).find("state in " + escaped + "\n") != std::string::npos; }));
  CHECK(read_text_file(log).find(escaped + "/jobs/9: cannot restore the job: status.json: missing, though the "
                                 "folder holds frame-0001.rgbf; moved whole to " + escaped +
                                 "/damaged/9, the other jobs go on") != std::string::npos);
}

TEST_CASE("service: workers stay up across jobs and load the next scene while the last rows finish" *
          doctest::timeout(120)) {
  const std::string dir = fresh_dir("overlap");
  Farm farm(dir + "/state");
  farm.start_broker();
  farm.start_worker(200);  // job a takes seconds: its last quarter hides the load of job b
  farm.start_worker(200);
  const std::string first = balls(), second = scene_file(dir, 6);
  const uint64_t a = submit(farm, first);
  const uint64_t b = submit(farm, second);
  REQUIRE(test::run_command(farm.cli("fetch " + std::to_string(b) + " -o " + dir + "/b.png --wait")).exit_code == 0);
  REQUIRE(test::run_command(farm.cli("fetch " + std::to_string(a) + " -o " + dir + "/a.png")).exit_code == 0);
  CHECK(read_text_file(dir + "/a.png") == reference_render(first, dir + "/a-ref.png"));
  CHECK(read_text_file(dir + "/b.png") == reference_render(second, dir + "/b-ref.png"));
  for (auto& w : farm.workers) CHECK(w->running());  // the same processes served both jobs

  const auto record = [&](uint64_t job) {
    return read_json_file(dir + "/state/jobs/" + std::to_string(job) + "/record-0001.json");
  };
  const json ra = record(a), rb = record(b);
  REQUIRE(rb["workers"].size() == 2);
  int loaded_early = 0;
  for (const json& w : rb["workers"]) {
    CHECK(w["state"] == "active");
    loaded_early += w["ready_at"].get<double>() < 0;  // ready before job b began: loaded during job a
  }
  CHECK(loaded_early >= 1);
  MESSAGE("gap from job a's last row to job b's first: ", rb["gap_s"].dump(), " s; workers loaded early: ",
          loaded_early);
  for (const json& w : ra["workers"]) CHECK(w["state"] == "active");
}

TEST_CASE("service: a frame beyond the broker's image limit is refused at the door or fails after a restart"
          " while the service goes on" * doctest::timeout(120)) {
  const std::string dir = fresh_dir("too-large");
  Farm farm(dir + "/state");
  farm.start_broker();  // the limit is this machine's memory: 512x512 (3 MiB) is taken
  const std::string large = scene_file(dir, 0, 512, 512);
  const uint64_t job = submit(farm, large);
  ApiClient api(farm.url());
  REQUIRE(eventually(30, [&] { return api.status(job)["state"] == "running"; }));  // waiting for a worker
  farm.broker->kill(SIGKILL);
  REQUIRE(farm.broker->wait_for(5));

  // Restarted with a smaller limit (an operator's, or a smaller machine's), the
  // service would otherwise resume the job into an image it cannot hold.
  const std::string config = test::write_file(dir + "/broker.json", R"({"max_image_mib": 1})");
  farm.start_broker("0", "*", {"--config", config});
  farm.start_worker(1);
  ApiClient restarted(farm.url());
  REQUIRE(eventually(30, [&] { return restarted.status(job)["state"] == "failed"; }));
  CHECK(restarted.status(job)["error"].get<std::string>() ==
        "a 512x512 image needs 3.0 MiB as float RGB; this broker's image limit (max_image_mib, or its memory) is "
        "1.0 MiB");

  const auto refused = test::run_command(farm.cli("submit " + large));
  CHECK(refused.exit_code != 0);
  CHECK(refused.output.find("a 512x512 image needs 3.0 MiB as float RGB; the broker's image limit is 1.0 MiB") !=
        std::string::npos);
  const std::string small = scene_file(dir, 1);
  const uint64_t next = submit(farm, small);
  REQUIRE(test::run_command(farm.cli("fetch " + std::to_string(next) + " -o " + dir + "/next.png --wait")).exit_code ==
          0);
  CHECK(read_text_file(dir + "/next.png") == reference_render(small, dir + "/next-ref.png"));
}

TEST_CASE("service: a frame within the image limit that the head node's memory cannot hold fails its job, and the"
          " next job runs" * doctest::timeout(120)) {
#if defined(__SANITIZE_ADDRESS__)
  MESSAGE("AddressSanitizer reserves more address space than the memory limit this test sets: skipped");
  return;
#endif
  const std::string dir = fresh_dir("memory");
  Farm farm(dir + "/state");
  farm.memory_limit_kib = size_t(4) << 20;  // 4 GiB; the frame needs 48
  const std::string config = test::write_file(dir + "/broker.json", R"({"max_image_mib": 1048576})");  // 1 TiB
  farm.start_broker("0", "*", {"--config", config});
  farm.start_worker(1);
  const auto r = test::run_command(farm.cli("submit " + scene_file(dir, 0) + " --width 65536 --height 65536 --spp 1"));
  REQUIRE_MESSAGE(r.exit_code == 0, r.output);
  const uint64_t huge = std::stoull(r.output);
  ApiClient api(farm.url());
  REQUIRE(eventually(30, [&] { return api.status(huge)["state"] == "failed"; }));
  CHECK(api.status(huge)["error"].get<std::string>() ==
        "the broker ran out of memory for this 65536x65536 frame (48.0 GiB as float RGB)");
  const std::string next_scene = scene_file(dir, 1);
  const uint64_t next = submit(farm, next_scene);
  REQUIRE(test::run_command(farm.cli("fetch " + std::to_string(next) + " -o " + dir + "/n.png --wait")).exit_code == 0);
  CHECK(read_text_file(dir + "/n.png") == reference_render(next_scene, dir + "/n-ref.png"));
  CHECK(farm.broker->running());
}

TEST_CASE("service: beyond loopback the API needs a token, and --serve takes no scene or image options" * doctest::timeout(60)) {
  const std::string dir = fresh_dir("refuse");
  const std::string serve = test::rayfarm_exe() + " broker --serve --state " + dir +
                            "/state --bind 'tcp://127.0.0.1:*' --announce 'tcp://127.0.0.1:*' ";
  const auto open = test::run_command(serve + "--http 0.0.0.0:0");
  CHECK(open.exit_code != 0);
  CHECK(open.output.find("needs a bearer token (--token-file)") != std::string::npos);
  const auto scene = test::run_command(serve + "--http 127.0.0.1:0 " + scene_file(dir, 0) + " -o x.png");
  CHECK(scene.exit_code != 0);
  CHECK(scene.output.find("not a scene on its command line") != std::string::npos);
  // Image options would be ignored: every job brings its own.
  for (const char* option : {"--spp 64", "--adaptive", "--width 640"}) {
    CAPTURE(option);
    const auto knob = test::run_command(serve + "--http 127.0.0.1:0 " + option);
    CHECK(knob.exit_code != 0);
    CHECK(knob.output.find("each job brings its own image options") != std::string::npos);
  }
  const auto no_state = test::run_command(test::rayfarm_exe() + " broker --serve");
  CHECK(no_state.output.find("needs --state DIR") != std::string::npos);
}

TEST_CASE("service: a worker side that cannot start (an allow folder others may write, a port in use) is said, "
          "not a hang" * doctest::timeout(60)) {
  // The HTTP API, started first, was dropped before its listen loop began,
  // and httplib's stop() then did nothing: the loop accepted forever and the
  // broker hung at start, saying nothing.
  const std::string dir = fresh_dir("worker-side");
  const std::string keys = dir + "/keys";
  std::filesystem::create_directories(keys + "/allow");
  REQUIRE(test::run_command(test::rayfarm_exe() + " keygen -o " + keys + "/broker").exit_code == 0);
  REQUIRE(test::run_command(test::rayfarm_exe() + " keygen -o " + keys + "/allow/w1").exit_code == 0);
  std::filesystem::permissions(keys + "/allow", std::filesystem::perms::others_write, std::filesystem::perm_options::add);
  // A race, lost most times: tried a few times over.
  for (int attempt = 0; attempt < 5; ++attempt) {
    CAPTURE(attempt);
    const auto refused = test::run_command("timeout 10 " + test::rayfarm_exe() + " broker --serve --state " + dir +
                                           "/state --http 127.0.0.1:0 --bind 'tcp://127.0.0.1:*' --announce "
                                           "'tcp://127.0.0.1:*' --key " + keys + "/broker.key --allow " + keys +
                                           "/allow");
    CHECK(refused.exit_code == 1);
    CHECK(refused.output.find(keys + "/allow: writable by others") != std::string::npos);
  }
}

TEST_CASE("broker: an option of the other mode is refused, not ignored (--record with --serve, --state without)" *
          doctest::timeout(60)) {
  const std::string dir = fresh_dir("modes");
  // Ignored, either command would run on (serving, or waiting for workers): `timeout` ends it.
  const std::string broker =
      "timeout 10 " + test::rayfarm_exe() + " broker --bind 'tcp://127.0.0.1:*' --announce 'tcp://127.0.0.1:*' ";
  // Each refusal says what the service does instead (--shutdown-workers has nothing to do with job records).
  const std::pair<const char*, const char*> one_job_options[] = {
      {"--record r.json", "keeps each frame's job record in DIR/jobs/ID/"},
      {"--stats s.json", "its ray counts and times included"},
      {"--shutdown-workers", "keeps its workers from job to job"}};
  for (const auto& [option, instead] : one_job_options) {
    CAPTURE(option);
    const auto r = test::run_command(broker + "--serve --state " + dir + "/state --http 127.0.0.1:0 " + option);
    CHECK(r.exit_code != 0);
    CHECK(r.output.find("is an option of one job") != std::string::npos);
    CHECK(r.output.find(instead) != std::string::npos);
  }
  for (const std::string& option :
       {"--state " + dir + "/state", std::string("--http 127.0.0.1:0"), "--token-file " + test::source_dir() + "/README.md"}) {
    CAPTURE(option);
    const auto r = test::run_command(broker + scene_file(dir, 0) + " -o " + dir + "/x.png " + option);
    CHECK(r.exit_code != 0);
    CHECK(r.output.find("goes with --serve") != std::string::npos);
  }
}

TEST_CASE("status: a bad broker URL from $RAYFARM_BROKER is named as the variable, not as --broker") {
  const std::string bad = "http://127.0.0.1:1/api";
  const auto from_variable = test::run_command("RAYFARM_BROKER=" + bad + " " + test::rayfarm_exe() + " status");
  CHECK(from_variable.exit_code != 0);
  CHECK(from_variable.output.find("$RAYFARM_BROKER: '" + bad + "' has a path") != std::string::npos);
  const auto from_option =
      test::run_command("RAYFARM_BROKER=http://127.0.0.1:1 " + test::rayfarm_exe() + " status --broker " + bad);
  CHECK(from_option.exit_code != 0);
  CHECK(from_option.output.find("--broker: '" + bad + "' has a path") != std::string::npos);
}

TEST_CASE("status, fetch, cancel: a job's error text reaches the terminal with its control characters escaped") {
  // A worker's message, in a scene's name: it would retitle the terminal (OSC
  // ... BEL), clear it (CSI 2J, also as the one C1 character CSI), overwrite the line (CR).
  const std::string raw = "job 7 (evil\x1b]0;owned\x07.nff) failed on the workers: w1: \x1b[2J\rfake\xc2\x9b" "31m";
  const std::string shown = "job 7 (evil\\x1b]0;owned\\x07.nff) failed on the workers: w1: \\x1b[2J\\rfake\\u009b31m";
  const json status = {{"id", 7},           {"state", "failed"}, {"priority", 0},       {"order", 7},
                       {"frames", 1},       {"frames_done", 0},  {"rows_done", 0},      {"rows_total", 24},
                       {"resumed_rows", 0}, {"error", raw},      {"rerendered_rows", 0},
                       {"scenes", json::array({"evil\x1b]0;owned\x07.nff"})}};
  httplib::Server broker;
  broker.Get("/api/jobs", [&](const httplib::Request&, httplib::Response& res) {
    res.set_content(json::array({status}).dump(), "application/json");
  });
  broker.Get("/api/jobs/7", [&](const httplib::Request&, httplib::Response& res) {
    res.set_content(status.dump(), "application/json");
  });
  broker.Post("/api/jobs/7/cancel", [&](const httplib::Request&, httplib::Response& res) {
    res.status = 409;
    res.set_content(json{{"error", "job 7 (evil\x1b]0;owned\x07.nff) is already failed"}}.dump(), "application/json");
  });
  const int port = broker.bind_to_any_port("127.0.0.1");
  REQUIRE(port > 0);
  std::thread serving([&broker] { broker.listen_after_bind(); });
  const std::string url = " --broker http://127.0.0.1:" + std::to_string(port);
  const std::string dir = fresh_dir("terminal-escapes");
  for (const std::string& args :
       std::vector<std::string>{"status", "status 7", "status 7 --json", "fetch 7 -o " + dir + "/x.png", "cancel 7"}) {
    CAPTURE(args);
    const auto r = test::run_command(test::rayfarm_exe() + " " + args + url);
    CAPTURE(r.output);
    CHECK(r.output.find_first_of("\x1b\x07\r") == std::string::npos);
    CHECK(r.output.find("\xc2\x9b") == std::string::npos);
    CHECK(r.output.find("evil\\") != std::string::npos);  // escaped, not dropped: the reason still reads whole
  }
  CHECK(test::run_command(test::rayfarm_exe() + " status 7" + url).output.find("  (" + shown + ")\n") !=
        std::string::npos);
  CHECK(test::run_command(test::rayfarm_exe() + " fetch 7 -o " + dir + "/x.png" + url).output ==
        "rayfarm: job 7 is failed: " + shown + "\n");
  const json printed = json::parse(test::run_command(test::rayfarm_exe() + " status 7 --json" + url).output);
  CHECK(printed == status);  // the same JSON, its C1 control written as \u009b
  broker.stop();
  serving.join();
}

TEST_CASE("submit: -o without --wait is refused before anything is queued, not ignored") {
  const std::string dir = fresh_dir("submit-output");
  // An unreachable broker: the check comes first, so no job could have been queued.
  const auto r = test::run_command(test::rayfarm_exe() + " submit " + scene_file(dir, 0) + " -o " + dir +
                                   "/x.png --broker http://127.0.0.1:1");
  CHECK(r.exit_code != 0);
  CHECK(r.output.find("-o OUT needs --wait") != std::string::npos);
}

TEST_CASE("submit --wait and fetch: an -o that cannot be written is refused before the job is queued or fetched") {
  const std::string dir = fresh_dir("unwritable-output");
  const std::string out = dir + "/no-such-folder/x.png";
  // An unreachable broker: the check comes first, so nothing was queued or rendered in vain.
  for (const std::string& args : {"submit " + scene_file(dir, 0) + " --wait -o " + out, "fetch 1 -o " + out}) {
    CAPTURE(args);
    const auto r = test::run_command(test::rayfarm_exe() + " " + args + " --broker http://127.0.0.1:1");
    CHECK(r.exit_code != 0);
    CHECK(r.output.find(out + ": cannot write") != std::string::npos);
  }
}

TEST_CASE("fetch: a job still to finish, fetched without --wait, says how to wait for it") {
  const std::string dir = fresh_dir("fetch-unfinished");
  Farm farm(dir + "/state");
  farm.start_broker();
  const uint64_t job = submit(farm, scene_file(dir, 0));  // no worker: it never finishes
  const auto r = test::run_command(farm.cli("fetch " + std::to_string(job) + " -o " + dir + "/out.png"));
  CHECK(r.exit_code == 1);
  CHECK_MESSAGE(r.output.find("(add --wait to wait for it and write its frames)") != std::string::npos, r.output);
  CHECK(!fs::exists(dir + "/out.png"));
}

TEST_CASE("submit --idempotency-key: run again, also after a restart, it prints the first job's id, not a second"
          * doctest::timeout(60)) {
  const std::string dir = fresh_dir("idempotency-key");
  Farm farm(dir + "/state");
  farm.start_broker();
  const std::string scene = scene_file(dir, 0), other = scene_file(dir, 1);
  // stdout alone: the id; stderr says the job was held already.
  const auto keyed = [&](const std::string& key) {
    const auto r = test::run_command("(" + farm.cli("submit " + scene + " --spp 4 --idempotency-key " + key) +
                                     " 2>/dev/null)");
    REQUIRE_MESSAGE(r.exit_code == 0, r.output);
    return std::stoull(r.output);
  };
  const uint64_t job = keyed("render-42");
  CHECK(keyed("render-42") == job);
  const auto told = test::run_command(farm.cli("submit " + scene + " --spp 4 --idempotency-key render-42"));
  CHECK(told.output == "rayfarm: the broker already held this submission (Idempotency-Key render-42): job " +
                           std::to_string(job) + ", not a second one\n" + std::to_string(job) + "\n");
  const uint64_t fresh = submit(farm, scene);  // a random key of its own: a second job
  CHECK(fresh != job);
  farm.broker->kill(SIGKILL);
  REQUIRE(farm.broker->wait_for(5));
  farm.start_broker();
  CHECK(keyed("render-42") == job);
  const auto refused = test::run_command(farm.cli("submit " + other + " --spp 4 --idempotency-key render-42"));
  CHECK(refused.exit_code != 0);
  CHECK(refused.output.find("Idempotency-Key 'render-42': already used by job " + std::to_string(job)) !=
        std::string::npos);
  CHECK(ApiClient(farm.url()).list().size() == 2);
  const std::pair<std::string, std::string> bad_keys[] = {
      {"''", "--idempotency-key: empty value"},
      {"\"$(printf 'a\\tb')\"",
       "--idempotency-key: expected 1 to 255 printable ASCII characters, found byte 0x09 at character 2"}};
  for (const auto& [key, reason] : bad_keys) {
    CAPTURE(key);
    const auto bad = test::run_command(farm.cli("submit " + scene + " --idempotency-key " + key));
    CHECK(bad.exit_code != 0);
    CHECK_MESSAGE(bad.output.find(reason) != std::string::npos, bad.output);
  }
  CHECK(ApiClient(farm.url()).list().size() == 2);
}
