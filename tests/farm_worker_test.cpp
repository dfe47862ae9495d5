// A real worker (on a thread of the test) against real brokers and
// hand-driven ones (HandBroker, tests/farm_peers.h): what it does when its
// broker is missing, unresolvable, of another protocol version or
// restarted, and when a broker sends what it should not (tasks of a job it
// does not hold, a flood of announcements, a stop in the middle of a task).
// Real sockets on tcp://127.0.0.1 ephemeral ports; every wait is bounded.
#include <doctest/doctest.h>

#include <chrono>
#include <csignal>
#include <map>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <variant>
#include <vector>

#include "broker/broker.h"
#include "spd/generators.h"
#include "tests/farm_peers.h"
#include "tests/test_files.h"
#include "worker/worker.h"
#include "worker/worker_config.h"

using namespace rayfarm;
using namespace rayfarm::protocol;
using namespace rayfarm::test;
using Clock = std::chrono::steady_clock;

TEST_CASE("farm: a worker survives a broker restart: it reconnects and registers again") {
  const FarmJob job = small_job(32, 16, 1);
  std::string endpoint;
  LogCapture worker_log;
  std::unique_ptr<ThreadWorker> worker;
  {
    Broker first(test_broker_config(1), [](const std::string&) {});
    endpoint = first.endpoint();
    WorkerConfig c = thread_worker_config(endpoint, "survivor");
    c.quiet = false;
    worker = std::make_unique<ThreadWorker>(c, nullptr, worker_log.sink());
    const FarmResult r = first.run(job, deadline(30));
    CHECK(identical(r.rgb, in_process(job)));
  }  // broker gone without a word
  std::this_thread::sleep_for(std::chrono::milliseconds(900));  // > 5 missed heartbeats
  BrokerConfig cfg = test_broker_config(1);
  cfg.bind = endpoint;  // the same port, as a restarted head node would use
  Broker second(cfg, [](const std::string&) {});
  const FarmResult r = second.run(job, deadline(30));
  CHECK(identical(r.rgb, in_process(job)));
  CHECK(worker_entry(r.record, "survivor")["rows"] == 16);
  CHECK(worker_log.count("reconnecting") >= 1);
  CHECK(worker_log.count("registered with") >= 2);
  second.shutdown_workers();
  worker.reset();
}


TEST_CASE("farm: a worker no broker has answered says so and where, not 'broker silent'") {
  std::string endpoint;
  {
    Broker gone(test_broker_config(1), [](const std::string&) {});  // a port free a moment ago
    endpoint = gone.endpoint();
  }
  LogCapture log;
  WorkerConfig c = thread_worker_config(endpoint, "early");
  c.quiet = false;
  ThreadWorker worker(c, nullptr, log.sink());
  const auto start = Clock::now();
  while (log.count("reconnecting") == 0 && Clock::now() - start < std::chrono::seconds(5))
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  CHECK(log.count("no broker answered at " + endpoint + " within 500 ms; reconnecting") >= 1);
  CHECK(log.count("broker silent") == 0);
}

TEST_CASE("farm: a worker refused for its protocol version stops, naming both versions, with status 1") {
  // It logged "rejected message from broker: v: unsupported protocol version"
  // and "no broker answered", and retried for ever.
  zmq::context_t ctx(1);
  zmq::socket_t router(ctx, zmq::socket_type::router);
  router.bind("tcp://127.0.0.1:*");
  const std::string endpoint = router.get(zmq::sockopt::last_endpoint);
  LogCapture log;
  WorkerConfig c = thread_worker_config(endpoint, "old");
  c.quiet = false;
  ThreadWorker worker(c, nullptr, log.sink());
  // The routing id of the worker's next `ready` ("" if none came within `seconds`).
  auto next_ready = [&](int seconds = 5) {
    const auto end = Clock::now() + std::chrono::seconds(seconds);
    std::string identity;
    while (Clock::now() < end) {
      zmq::pollitem_t item{router.handle(), 0, ZMQ_POLLIN, 0};
      zmq::poll(&item, 1, std::chrono::milliseconds(20));
      while (auto frames = receive(router, &identity))
        if (std::holds_alternative<Ready>(decode(*frames))) return identity;
    }
    return std::string();
  };
  REQUIRE_FALSE(next_ready().empty());
  // Unanswered, it retries as before: a broker not yet up is no reason to stop.
  const std::string identity = next_ready();
  REQUIRE_FALSE(identity.empty());
  CHECK(log.count("no broker answered at " + endpoint) >= 1);
  // A broker one version ahead refuses it, as this version's broker refuses another's.
  const int newer = kVersion + 1;
  const std::string reason = "refused: v: unsupported protocol version " + std::to_string(kVersion) + " (this is " +
                             std::to_string(newer) + ")";
  REQUIRE(protocol::send(router, Frames{nlohmann::json{{"v", newer}, {"type", "reregister"}, {"reason", reason}}.dump()},
                         &identity));
  const auto start = Clock::now();
  while (log.count("this worker stops") == 0 && Clock::now() - start < std::chrono::seconds(5))
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  CHECK(log.count("the broker at " + endpoint + " speaks protocol version " + std::to_string(newer) +
                  " and this worker version " + std::to_string(kVersion) + " (the broker said: " + reason +
                  "); they cannot work together, so this worker stops") == 1);
  CHECK(next_ready(2).empty());  // no retry: one came every 0.6-0.9 s
  CHECK(worker.finish() == 1);
  CHECK(log.count("rejected message from broker") == 0);
  // The envelope is all that is read of another version's message.
  CHECK(other_version({R"({"v":3,"type":"heartbeat","job":0})"})->version == 3);
  CHECK_FALSE(other_version(encode(Message{Reregister{"unknown worker: send ready"}})));
  CHECK_FALSE(other_version({"{not json"}));
}

TEST_CASE("farm: a worker given a broker host name that does not resolve says so at once and as it retries") {
  // It said "no broker answered" for ever, as if a broker were merely down.
  const std::string endpoint = "tcp://nonexistent.invalid:47601";
  LogCapture log;
  WorkerConfig c = thread_worker_config(endpoint, "lost");
  c.quiet = false;
  {
    ThreadWorker worker(c, nullptr, log.sink());
    const auto start = Clock::now();
    while (log.count("reconnecting") == 0 && Clock::now() - start < std::chrono::seconds(5))
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  const std::string problem = "cannot reach the broker at " + endpoint + ": the host name 'nonexistent.invalid' " +
                              "cannot be resolved (";
  CHECK(log.count(problem) >= 2);  // at start, and on the first retry
  CHECK(log.count("retrying until it resolves") == 1);
  CHECK(log.count("no broker answered") == 0);
  // Addresses and names that resolve are no problem.
  CHECK(tcp_host_problem("tcp://127.0.0.1:47601") == "");
  CHECK(tcp_host_problem("tcp://[::1]:47601") == "");
  CHECK(tcp_host_problem("tcp://localhost:47601") == "");
  CHECK(tcp_host_problem("tcp://*:47601") == "");
  CHECK(tcp_host_problem("ipc:///tmp/x") == "");
}

TEST_CASE("farm: a worker given an announce host name that does not resolve says so at once") {
  // The broker socket was checked, --subscribe not: the worker rendered on,
  // fetching each job late, and nothing said the announcements never came.
  Broker broker(test_broker_config(1), [](const std::string&) {});
  LogCapture log;
  WorkerConfig c = thread_worker_config(broker.endpoint(), "deaf");
  c.subscribe = "tcp://nonexistent.invalid:47602";
  c.quiet = true;  // said even so: it is a configuration error
  const FarmJob job = small_job(16, 16, 1);
  {
    ThreadWorker worker(c, nullptr, log.sink());
    const FarmResult r = broker.run(job, deadline(30));
    CHECK(identical(r.rgb, in_process(job)));  // it still renders
    broker.shutdown_workers();
  }
  CHECK(log.count("cannot subscribe to the broker's announcements at tcp://nonexistent.invalid:47602: the host "
                  "name 'nonexistent.invalid' cannot be resolved (") == 1);
}

TEST_CASE("farm: a worker whose announce endpoint cannot be reached says so once, naming it, and one that hears says nothing") {
  // A port refused (or firewalled, or another socket's) was dialled again and
  // again in silence: the worker rendered on, fetching each job late.
  std::string refused;
  {
    zmq::context_t ctx;
    zmq::socket_t gone(ctx, zmq::socket_type::pub);  // a port free a moment ago
    gone.set(zmq::sockopt::linger, 0);
    gone.bind("tcp://127.0.0.1:*");
    refused = gone.get(zmq::sockopt::last_endpoint);
  }
  Broker broker(test_broker_config(2), [](const std::string&) {});
  LogCapture deaf_log, hearing_log;
  WorkerConfig deaf = thread_worker_config(broker.endpoint(), "deaf");
  deaf.subscribe = refused;
  deaf.quiet = true;  // said even so: no announcement will come
  WorkerConfig hearing = thread_worker_config(broker.endpoint(), "hearing");
  hearing.quiet = false;
  const std::string said = "cannot subscribe to the broker's announcements at " + refused +
                           " (--subscribe): no connection there completed within 500 ms";
  const FarmJob job = small_job(16, 16, 1);
  const std::vector<float> image = in_process(job);
  {
    ThreadWorker w1(deaf, nullptr, deaf_log.sink()), w2(hearing, nullptr, hearing_log.sink());
    // Jobs one after another keep both workers registered (between run()s
    // the broker is silent): until the line comes, then three liveness periods more.
    const auto start = Clock::now();
    std::optional<Clock::time_point> said_at;
    while (Clock::now() - start < std::chrono::seconds(20) &&
           (!said_at || Clock::now() - *said_at < std::chrono::milliseconds(1500))) {
      const FarmResult r = broker.run(job, deadline(30));
      REQUIRE(identical(r.rgb, image));  // it still renders
      if (!said_at && deaf_log.count(said) > 0) said_at = Clock::now();
    }
    broker.shutdown_workers();
  }
  CHECK(deaf_log.count(said) == 1);
  CHECK(deaf_log.count("announcements") == 1);
  CHECK(hearing_log.count("registered with") == 1);
  CHECK(hearing_log.count("announcements") == 0);
}

TEST_CASE("farm: a broker restarted within the worker's liveness gets one registration, not one per queued heartbeat") {
  BrokerConfig cfg = test_broker_config(1);
  cfg.liveness = 40;  // 4 s at 100 ms heartbeats: the worker waits out the restart on its connection
  std::unique_ptr<ThreadWorker> worker;
  LogCapture first_log, second_log;
  {
    Broker first(cfg, first_log.sink());
    cfg.bind = first.endpoint();  // the same port, as a restarted head node would use
    worker = std::make_unique<ThreadWorker>(thread_worker_config(cfg.bind, "patient"));
    first.serve_for(1.0);
  }  // broker gone without a word
  REQUIRE(first_log.count("worker patient#1 registered") == 1);
  // Heartbeats queue on the worker's connection meanwhile; the new broker
  // answers each with `reregister`.
  std::this_thread::sleep_for(std::chrono::milliseconds(1000));
  Broker second(cfg, second_log.sink());
  second.serve_for(2.0);
  CHECK(second_log.count("registered: weight") == 1);
  CHECK(second_log.count("re-registered") == 0);
  second.shutdown_workers();
  worker.reset();
}

TEST_CASE("farm: a burst of tasks of a job the worker does not hold gets one registration, not one per task") {
  // Each such task sent another `ready`, each registering the worker again
  // at the broker: 20 of them, 20 registrations and 20 log lines. The first
  // `ready` already has the broker requeue every task it sent before it.
  HandBroker broker;
  LogCapture log;
  ThreadWorker worker(thread_worker_config(broker.endpoint, "w1"), nullptr, log.sink());
  REQUIRE(broker.wait_for<Ready>(5));
  broker.send_message(Welcome{100, 5, 1, 0});
  broker.listen(0.3);
  for (uint32_t task = 1; task <= 20; ++task) broker.send_message(TaskAssign{77, task, 1, 0, 1, 0, 16});
  int readies = 0;
  for (const Message& m : broker.listen(1.0)) readies += std::holds_alternative<Ready>(m);
  CHECK(readies == 1);
  CHECK(log.count("got a task of job 77, which is not loaded; registering again") == 1);
  // Once welcomed, a task it does not hold still has it register again.
  broker.send_message(Welcome{100, 5, 1, 0});
  broker.listen(0.3);
  broker.send_message(TaskAssign{77, 21, 1, 0, 1, 0, 16});
  CHECK(broker.wait_for<Ready>(2));
  CHECK(log.count("got a task of job 77") == 2);
}

TEST_CASE("farm: a flood of job announcements loads the last two jobs, not a queued scene copy per announcement") {
  // Every announced job was queued for loading with its scene text (up to
  // 256 MiB each): a broker announcing 100 jobs of an 8 MiB scene grew the
  // worker by 600 MB, and it loaded every one of them in turn.
  HandBroker broker;
  ThreadWorker worker(thread_worker_config(broker.endpoint, "w1"));
  REQUIRE(broker.wait_for<Ready>(5));
  broker.send_message(Welcome{100, 5, 1, 0});
  broker.listen(0.3);
  // Slow enough to load that announcements arrive faster than it loads.
  std::string scene =
      "v\nfrom 0 0 -60\nat 0 0 0\nup 0 1 0\nangle 45\nhither 0\nresolution 8 8\nl 0 5 -10\nf 1 0 0 1 0 0 0 1\n";
  for (int i = 0; i < 20000; ++i)
    scene += "s " + std::to_string(i % 100 - 50) + " " + std::to_string(i / 100 % 100 - 50) + " " +
             std::to_string(i / 10000) + " 0.4\n";
  RenderSettings settings = small_settings(8, 8, 1);
  constexpr int kJobs = 40;
  for (int job = 1; job <= kJobs; ++job) {
    settings.seed = job;  // each its own load, none the cache's
    broker.send_message(JobSpec{uint64_t(job), fnv1a64(scene), "many.nff", settings, scene});
  }
  std::vector<uint64_t> ready;
  while (auto r = broker.wait_for<JobReady>(ready.empty() || ready.back() != kJobs ? 10.0 : 0.5))
    ready.push_back(r->job);
  REQUIRE_FALSE(ready.empty());
  // The one loading when the others came and the last two; a few more if a
  // load ends before the next announcement is in (a slow machine, sanitizers).
  CHECK(ready.size() <= 10);
  CHECK(ready.back() == kJobs);
}

// A worker of a hand-played broker, half a second into a task of half a
// minute or more (job 5, one thread): the cases of a task stopped mid-way.
struct WorkerMidTask {
  HandBroker broker;
  ThreadWorker worker{thread_worker_config(broker.endpoint, "w1")};
  const FarmJob job = small_job(512, 64, 4096);

  WorkerMidTask() {
    broker.welcome_with(job, 5);
    broker.send_message(TaskAssign{5, 1, 1, 0, 64, 0, 512});
    broker.listen(0.5);  // rendering
  }
};

TEST_CASE("farm: a worker told to shut down mid-task stops at once, not after the task") {
  // It logged "shutdown by broker" and then rendered on, for the minutes a
  // large task takes, silent to the broker and deaf to SIGTERM meanwhile.
  WorkerMidTask mid;
  HandBroker& broker = mid.broker;
  broker.send_message(Shutdown{});
  const auto start = Clock::now();
  CHECK(mid.worker.finish() == 0);
  CHECK(Clock::now() - start < std::chrono::seconds(5));
  for (const Message& m : broker.listen(0.2)) CHECK_FALSE(std::holds_alternative<TaskResult>(m));  // a `bye` may come
}

TEST_CASE("farm: a broker that re-registers the worker with another announce port is heard on that port") {
  // The worker kept its subscription to the first port: announcements on the
  // new one (a broker restarted with another --announce) never reached it.
  HandBroker broker;
  zmq::socket_t old_pub(broker.ctx, zmq::socket_type::pub), new_pub(broker.ctx, zmq::socket_type::pub);
  for (zmq::socket_t* pub : {&old_pub, &new_pub}) {
    pub->set(zmq::sockopt::linger, 0);
    pub->bind("tcp://127.0.0.1:*");
  }
  const int old_port = endpoint_port(old_pub.get(zmq::sockopt::last_endpoint));
  const int new_port = endpoint_port(new_pub.get(zmq::sockopt::last_endpoint));
  LogCapture log;
  WorkerConfig c = thread_worker_config(broker.endpoint, "w1");
  c.quiet = false;
  ThreadWorker worker(c, nullptr, log.sink());
  REQUIRE(broker.wait_for<Ready>(5));
  broker.send_message(Welcome{100, 5, old_port, 0});
  broker.listen(0.3);
  broker.send_message(Reregister{"unknown worker"});
  REQUIRE(broker.wait_for<Ready>(5));
  broker.send_message(Welcome{100, 5, new_port, 0});
  // The job is only announced (welcome and heartbeats name none): a worker
  // that listens on the new port loads it. Repeated: a subscriber misses
  // what is published before it has connected.
  const FarmJob job = small_job(8, 8, 1);
  const JobSpec spec{9, fnv1a64(job.scene_text), job.scene_name, job.settings, job.scene_text};
  std::optional<JobReady> ready;
  for (int i = 0; i < 30 && !ready; ++i) {
    REQUIRE(protocol::send(new_pub, Message{spec}));
    ready = broker.wait_for<JobReady>(0.1);
  }
  REQUIRE(ready);
  CHECK(ready->job == 9);
  CHECK(log.count("the broker announces on port " + std::to_string(new_port) + " now, not " +
                  std::to_string(old_port) + "; subscribing there") == 1);
}

TEST_CASE("farm: tasks that come while the worker's ready is on its way are not rendered, the broker requeues them") {
  // They were rendered and their results sent: stale at the broker, which
  // requeued them on reading the `ready`, so each cost a task's time for nothing.
  HandBroker broker;
  ThreadWorker worker(thread_worker_config(broker.endpoint, "w1"));
  const FarmJob job = small_job(32, 16, 1);
  broker.welcome_with(job, 5);
  broker.send_message(TaskAssign{77, 1, 1, 0, 1, 0, 32});  // a job it does not hold: it registers again
  broker.send_message(TaskAssign{5, 2, 1, 0, 8, 0, 32});
  broker.send_message(TaskAssign{5, 3, 1, 8, 16, 0, 32});
  const std::vector<Message> heard = broker.listen(1.0);
  REQUIRE(heard.size() >= 1);
  CHECK(std::holds_alternative<Ready>(heard.front()));
  for (const Message& m : heard) CHECK_FALSE(std::holds_alternative<TaskResult>(m));
  // Once welcomed, it renders again.
  broker.send_message(Welcome{100, 5, 1, 5});
  broker.send_message(TaskAssign{5, 2, 2, 0, 8, 0, 32});
  const auto result = broker.wait_for<TaskResult>(5);
  REQUIRE(result);
  CHECK(result->task == 2);
  CHECK(result->attempt == 2);
}

TEST_CASE("farm: a broker of liveness 1 that heartbeats once an interval keeps its worker") {
  // The worker waited one interval: a broker heartbeats only after a whole
  // quiet interval, so every heartbeat came late and the worker reconnected
  // at the first one (and again at each, for as long as the link was quiet).
  HandBroker broker;
  LogCapture log;
  WorkerConfig c = thread_worker_config(broker.endpoint, "w1");
  c.quiet = false;
  ThreadWorker worker(c, nullptr, log.sink());
  REQUIRE(broker.wait_for<Ready>(5));
  broker.send_message(Welcome{100, 1, 1, 0});
  auto beat = Clock::now();
  int readies = 0;
  for (const auto end = Clock::now() + std::chrono::milliseconds(1500); Clock::now() < end;) {
    zmq::pollitem_t item{broker.router.handle(), 0, ZMQ_POLLIN, 0};
    zmq::poll(&item, 1, std::chrono::milliseconds(10));
    while (auto frames = receive(broker.router, &broker.identity))
      readies += std::holds_alternative<Ready>(decode(*frames));
    if (Clock::now() - beat >= std::chrono::milliseconds(100)) {  // as a broker does: after a quiet interval
      broker.send_message(Heartbeat{0});
      beat = Clock::now();
    }
  }
  CHECK(readies == 0);
  CHECK(log.count("reconnecting") == 0);
  CHECK(log.count("the broker's liveness 1 would count it gone at its first quiet heartbeat interval; waiting 2 "
                  "intervals (200 ms) instead") == 1);
}

TEST_CASE("farm: a broker of liveness 1 keeps a worker that heartbeats once an interval") {
  // The broker gave a worker one of its intervals: a worker heartbeats only
  // after a whole quiet interval, so each of its heartbeats came late and the
  // broker dropped it as lost at the first, requeueing its tasks.
  BrokerConfig cfg = test_broker_config(1);
  cfg.liveness = 1;
  LogCapture log;
  Broker broker(cfg, log.sink());
  ThreadWorker worker(thread_worker_config(broker.endpoint(), "w1"));
  broker.serve_for(1.5);
  CHECK(log.count("registered: weight") == 1);
  CHECK(log.count("lost") == 0);
  broker.shutdown_workers();
}

TEST_CASE("farm: a worker that registers again stops the task it was rendering, its result would not be sent") {
  // The task in progress rendered on to its end (half a minute here) while
  // the new registration's tasks waited behind it, and its result was dropped.
  WorkerMidTask mid;
  HandBroker& broker = mid.broker;
  const FarmJob& job = mid.job;
  broker.send_message(Reregister{"unknown worker: send ready"});  // a restarted broker
  REQUIRE(broker.wait_for<Ready>(5));
  broker.send_message(Welcome{100, 5, 1, 5});
  broker.send_message(TaskAssign{5, 1, 1, 0, 1, 0, 8});  // the new broker's first task: a few pixels
  const auto start = Clock::now();
  const auto result = broker.wait_for<TaskResult>(10);
  REQUIRE(result);
  CHECK(Clock::now() - start < std::chrono::seconds(5));
  // The scene whose render was stopped renders whole again.
  const Scene scene = parse_nff(job.scene_text, job.scene_name);
  CHECK(identical(result->rgb, render_task(Renderer(scene, job.settings), TaskAssign{5, 1, 1, 0, 1, 0, 8}).rgb));
}

TEST_CASE("farm: a worker stopped while it builds a large scene says bye and waits for the build, and a second SIGTERM"
          " ends it at once, said on stderr" * doctest::timeout(180)) {
  // A stop joins the load thread, and a parse and BVH build cannot be cut
  // short: the SPD tetra at size 10, some 90 MB of NFF and four million
  // triangles, takes seconds on one thread.
  std::ostringstream nff;
  spd::generate("tetra", 10, nff);
  const FarmJob big{nff.str(), "tetra-10.nff", small_settings(16, 16, 1)};
  const std::filesystem::path dir = scratch_dir("second-signal-worker");
  for (const bool twice : {false, true}) {
    CAPTURE(twice);
    const std::string log = (dir / (twice ? "twice.log" : "once.log")).string();
    HandBroker broker;
    ChildProcess worker("/bin/sh", {"-c", "exec \"$@\" 2>>\"" + log + "\"", "sh", rayfarm_exe(), "worker",
                                    "--connect", broker.endpoint, "--name", "w1", "--threads", "1"});
    REQUIRE(broker.wait_for<Ready>(15));
    broker.send_message(Welcome{100, 5, 1, 0});
    broker.send_message(JobSpec{5, fnv1a64(big.scene_text), big.scene_name, big.settings, big.scene_text});
    // Its `ready` again, sent after the job was taken: the job is loading.
    broker.send_message(Reregister{"the test asks"});
    REQUIRE(broker.wait_for<Ready>(15));
    worker.kill(SIGTERM);
    const std::vector<Message> heard = broker.listen<Bye>(15);
    REQUIRE(!heard.empty());
    REQUIRE(std::holds_alternative<Bye>(heard.back()));  // the clean stop is under way
    for (const Message& m : heard) CHECK_FALSE(std::holds_alternative<JobReady>(m));  // and the build too
    if (twice) worker.kill(SIGTERM);
    REQUIRE(worker.wait_for(120));
    const std::string said = read_text_file(log);
    if (twice) {
      // Dead of the signal (143 in a shell), not after the build.
      CHECK(describe_status(worker.status()) == "killed by signal " + std::to_string(SIGTERM));
      CHECK_MESSAGE(said.find("rayfarm: second SIGTERM: stopping now\n") != std::string::npos, said);
    } else {
      CHECK(describe_status(worker.status()) == "exit code 0");
      CHECK_MESSAGE(said.find("rayfarm: second") == std::string::npos, said);
    }
  }
}

TEST_CASE("farm: a worker fetches and fails each job it cannot render once, also with a second such job after it") {
  // It remembered only the last job it failed: with a second bad job
  // announced early while the first was still the broker's current one, the
  // heartbeats naming the first had it fetch that scene and fail it again,
  // and then the second again once it became current.
  HandBroker broker;
  LogCapture log;
  ThreadWorker worker(thread_worker_config(broker.endpoint, "w1"), nullptr, log.sink());
  REQUIRE(broker.wait_for<Ready>(5));
  broker.send_message(Welcome{100, 5, 1, 0});
  const std::string bad = "v\nfrom 0 0 5\nat 0 0 0\nup 0 1 0\nangle 45\nhither 0\nresolution 8 8\ns 0 0\n";
  auto spec_of = [&](uint64_t job) { return JobSpec{job, fnv1a64(bad), "bad.nff", small_settings(8, 8, 1), bad}; };
  int fetches = 0;
  std::map<uint64_t, int> failures;
  // As a broker serves: a heartbeat naming `current` each interval, the
  // scene to each fetch. Longer than the worker's refetch period (5 x 100 ms).
  auto serve = [&](uint64_t current, double seconds) {
    for (const auto end = Clock::now() + std::chrono::duration<double>(seconds); Clock::now() < end;) {
      broker.send_message(Heartbeat{current});
      for (const Message& m : broker.listen(0.1)) {
        if (auto* f = std::get_if<FetchJob>(&m)) {
          ++fetches;
          broker.send_message(spec_of(f->job));
        }
        if (auto* f = std::get_if<JobFailed>(&m)) ++failures[f->job];
      }
    }
  };
  serve(1, 1.0);  // job 1 is current: fetched, failed
  REQUIRE(failures[1] == 1);
  broker.send_message(spec_of(2));  // job 2 announced early: failed
  serve(1, 1.5);
  serve(2, 1.5);  // job 2 is current
  CHECK(fetches == 1);
  CHECK(failures[1] == 1);
  CHECK(failures[2] == 1);
  CHECK(log.count("cannot render job 1") == 1);
  CHECK(log.count("cannot render job 2") == 1);
}

TEST_CASE("farm: a worker given more threads than the machine runs says it renders on the machine's") {
  // It rendered on the machine's threads and told the broker so, but said
  // nothing where it was started; `render --threads` says it.
  HandBroker broker;
  LogCapture log;
  WorkerConfig c = thread_worker_config(broker.endpoint, "w1");
  c.threads = 4096;
  c.quiet = false;
  ThreadWorker worker(c, nullptr, log.sink());
  const auto ready = broker.wait_for<Ready>(5);
  REQUIRE(ready);
  const std::string machine = std::to_string(render_threads(0));
  CHECK(ready->threads == render_threads(0));
  CHECK(log.count("w1: threads 4096 (--threads, or \"threads\" in its config or lab): this machine runs " + machine +
                  " threads at once; rendering on " + machine) == 1);
  c.threads = render_threads(0);  // the machine's own count: nothing to say
  LogCapture quiet_log;
  HandBroker second;
  c.connect = second.endpoint;
  ThreadWorker exact(c, nullptr, quiet_log.sink());
  REQUIRE(second.wait_for<Ready>(5));
  CHECK(quiet_log.count("threads at once") == 0);
}
