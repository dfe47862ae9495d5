// Who may talk to a broker, and how much (broker/admission.h): real brokers on
// ephemeral ports, real Worker threads and hand-driven peers. A frame larger
// than the largest legitimate one is dropped by ZeroMQ before it arrives; with
// keys only invited CURVE keys get in, and a registration answers to its key.
#include <doctest/doctest.h>

#include <filesystem>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "broker/broker.h"
#include "protocol/curve_keys.h"
#include "protocol/transport.h"
#include "tests/farm_peers.h"
#include "tests/test_files.h"
#include "tracer/nff_reader.h"
#include "tracer/renderer.h"

using namespace rayfarm;
using namespace rayfarm::protocol;
using namespace rayfarm::test;
namespace fs = std::filesystem;

namespace {

BrokerConfig loopback_config() {
  BrokerConfig cfg;
  cfg.bind = cfg.announce_bind = "tcp://127.0.0.1:*";
  cfg.progress = false;
  cfg.min_workers = 0;
  return cfg;
}

}  // namespace

TEST_CASE("admission: the ROUTER's frame cap follows the largest legitimate result") {
  BrokerConfig cfg = loopback_config();
  cfg.max_image_width = 640;
  cfg.max_task_rows = 256;
  CHECK(max_worker_frame_bytes(cfg) == 112 + 640 * 256 * 12);
  cfg.max_task_rows = 1;
  CHECK(max_worker_frame_bytes(cfg) == protocol::kMaxJsonBytes);  // a JSON frame may be larger
  cfg.max_task_rows = 1000;
  cfg.policy = PolicyKind::weighted;  // adaptive sizes each task at dispatch (task_rows_for is 0)
  CHECK(task_rows_for(cfg, 1e6) == 1000);  // no task is cut taller than the cap allows
  CHECK(policy_options(cfg).max_task_rows == 1000);  // nor by the adaptive policy
}

TEST_CASE("admission: an oversized frame never reaches the broker") {
  LogCapture log;
  BrokerConfig cfg = loopback_config();
  cfg.max_image_width = 64;
  cfg.max_task_rows = 4;  // largest result 3,112 bytes: the 1 MiB JSON limit rules
  Broker broker(cfg, log.sink());
  zmq::context_t ctx(1);
  zmq::socket_t big(ctx, zmq::socket_type::dealer), small(ctx, zmq::socket_type::dealer);
  for (zmq::socket_t* s : {&big, &small}) {
    protocol::configure_socket(*s, protocol::kMaxBrokerFrameBytes);
    s->connect(broker.endpoint());
  }
  // 16 MiB from one peer: before the cap it arrived whole (and was rejected only then).
  REQUIRE(protocol::send(big, protocol::Frames{std::string(16u << 20, '{')}));
  REQUIRE(protocol::send(small, protocol::Frames{"{not json"}));
  broker.serve_for(1.0);
  CHECK(log.count("rejected message from unknown peer") == 1);  // the small one only
  CHECK(log.count("frame 1: invalid JSON") == 1);
}

// ---- CURVE and ZAP --------------------------------------------------------------

namespace {

struct Keys {
  fs::path dir = test::scratch_dir("admission-keys");
  CurveKeyPair broker = write_key_files((dir / "broker").string());
  CurveKeyPair alice, bob, mallory;
  Keys() {
    fs::create_directories(dir / "allow");
    alice = write_key_files((dir / "allow" / "alice").string());
    bob = write_key_files((dir / "allow" / "bob").string());
    mallory = write_key_files((dir / "mallory").string());  // not in allow/
  }
  ~Keys() { fs::remove_all(dir); }
  std::string file(const std::string& name) const { return (dir / name).string(); }
  BrokerConfig keyed_config() const {
    BrokerConfig cfg = test_broker_config(1);
    cfg.key_file = file("broker.key");
    cfg.allow_dir = file("allow");
    return cfg;
  }
  std::function<void(zmq::socket_t&)> client(const CurveKeyPair& own, const std::string& routing_id = "") const {
    const std::string server = broker.public_key;
    return [own, server, routing_id](zmq::socket_t& s) {
      make_curve_client(s, own, server);
      if (!routing_id.empty()) s.set(zmq::sockopt::routing_id, routing_id);
    };
  }
};

FarmJob tiny_job() {
  RenderSettings s;
  s.width = 16;
  s.height = 12;
  s.spp = 4;
  s.threads = 1;
  return {test::tiny_scene(), "tiny.nff", s};
}

// Serves `broker` on a thread for `seconds` while the test drives peers.
struct Serving {
  std::thread thread;
  Serving(Broker& broker, double seconds) : thread([&broker, seconds] { broker.serve_for(seconds); }) {}
  ~Serving() { thread.join(); }
};

}  // namespace

TEST_CASE("admission: CURVE without a ZAP handler admits any client that knows the server key") {
  // The reason the broker runs its own ZAP handler: a bare CURVE server only
  // proves the client knows the server's *public* key, which is no secret.
  const CurveKeyPair server = generate_curve_keypair(), stranger = generate_curve_keypair();
  zmq::context_t ctx(1);
  zmq::socket_t router(ctx, zmq::socket_type::router), dealer(ctx, zmq::socket_type::dealer);
  make_curve_server(router, server);
  router.bind("tcp://127.0.0.1:*");
  make_curve_client(dealer, stranger, server.public_key);
  dealer.connect(router.get(zmq::sockopt::last_endpoint));
  REQUIRE(protocol::send(dealer, Message{Heartbeat{0}}));
  zmq::pollitem_t item{router.handle(), 0, ZMQ_POLLIN, 0};
  zmq::poll(&item, 1, std::chrono::milliseconds(3000));
  std::string identity;
  CHECK(receive(router, &identity).has_value());  // admitted: anyone with the public key gets in
}

TEST_CASE("admission: with the broker's ZAP handler an unlisted key is refused, logged and never registers") {
  Keys keys;
  LogCapture log;
  Broker broker(keys.keyed_config(), log.sink());
  CHECK(log.count("CURVE: admitting 2 invited worker key(s)") == 1);
  zmq::context_t ctx(1);
  RawPeer mallory(ctx, broker.endpoint(), keys.client(keys.mallory));
  RawPeer plain(ctx, broker.endpoint());  // no CURVE at all
  RawPeer alice(ctx, broker.endpoint(), keys.client(keys.alice));
  {
    Serving serving(broker, 2.0);
    mallory.send_message(Ready{"mallory", 1e6, 1, 64, 100, 1.0});
    plain.send_message(Ready{"plain", 1e6, 1, 64, 100, 1.0});
    alice.send_message(Ready{"alice", 21.0, 1, 2, 100, 1.0});
    CHECK(alice.wait_for<Welcome>(1.5).has_value());
    CHECK_FALSE(mallory.wait_for<Welcome>(0.3).has_value());
    CHECK_FALSE(plain.wait_for<Welcome>(0.1).has_value());
  }
  CHECK(log.count("refused connection from 127.0.0.1: key " + keys.mallory.public_key + " is not invited") == 1);
  CHECK(log.count("worker alice#1 registered") == 1);
  CHECK(log.count("key alice") == 1);
  CHECK(log.count("registered") == 1);
  CHECK(log.count("mallory") == 0);  // its `ready` never arrived
}

TEST_CASE("admission: an unlisted worker never gets a task, the invited ones render the in-process image") {
  Keys keys;
  LogCapture log;
  Broker broker(keys.keyed_config(), log.sink());
  LogCapture mallory_log;
  auto keyed = [&](const std::string& name, const std::string& key) {
    WorkerConfig c = thread_worker_config(broker.endpoint(), name);
    c.key_file = keys.file(key);
    c.broker_key_file = keys.file("broker.pub");
    c.quiet = false;
    return c;
  };
  ThreadWorker mallory(keyed("mallory", "mallory.key"), nullptr, mallory_log.sink());
  ThreadWorker alice(keyed("alice", "allow/alice.key"));
  const FarmJob job = tiny_job();
  const FarmResult r = broker.run(job, deadline(30));
  CHECK(r.rgb == in_process(job));
  for (const auto& w : r.record["workers"]) CHECK(w["name"] != "mallory");
  // The tiny job can end before mallory's handshake reaches the broker: the
  // broker goes on answering handshakes (and no `ready`) until both sides
  // have said what they say of the refusal.
  const std::string refused = "refused connection from 127.0.0.1: key " + keys.mallory.public_key;
  const std::string told = "the broker refused this worker (authentication failed, status 400): its key " +
                           keys.mallory.public_key + " is not invited";
  for (int i = 0; i < 100 && (log.count(refused) == 0 || mallory_log.count(told) == 0); ++i) broker.serve_for(0.05);
  CHECK(log.count("registered") == 1);
  CHECK(log.count(refused) == 1);
  CHECK(mallory_log.count("registered with") == 0);
  // What the unlisted worker sees: a refusal naming its key, not a silent broker.
  CHECK(mallory_log.count(told) == 1);
}

TEST_CASE("admission: a worker holding another broker's public key is told so, and the broker logs the handshake") {
  // The broker cannot open such a worker's CURVE hello, so the ZAP handler is
  // never asked: without a watch on the handshake both sides stayed silent.
  Keys keys;
  LogCapture log, worker_log;
  Broker broker(keys.keyed_config(), log.sink());
  WorkerConfig c = thread_worker_config(broker.endpoint(), "alice");
  c.key_file = keys.file("allow/alice.key");  // invited
  c.broker_key_file = keys.file("mallory.pub");  // but not the broker's key
  {
    ThreadWorker alice(c, nullptr, worker_log.sink());
    Serving serving(broker, 2.0);
  }
  CHECK(log.count("registered") == 0);
  // Logged once, though the worker tried again and again.
  CHECK(log.count("failed: the peer does not hold this broker's public key " + keys.broker.public_key) == 1);
  CHECK(worker_log.count("closed the connection during the handshake: is that its worker port (not its announce port), "
                         "and does --broker-key " + keys.file("mallory.pub") + " (" + keys.mallory.public_key +
                         ") hold its public key?") >= 1);
}

TEST_CASE("admission: keys on one side only: the worker's advice fits its own configuration") {
  // A worker without keys was asked whether --broker-key and the broker's
  // key are the same pair: it has no --broker-key.
  Keys keys;
  LogCapture worker_log;
  BrokerConfig cfg = keys.keyed_config();
  Broker keyed(cfg, [](const std::string&) {});
  {
    ThreadWorker plain(thread_worker_config(keyed.endpoint(), "plain"), nullptr, worker_log.sink());
    Serving serving(keyed, 1.0);
  }
  // Refused (a protocol error) or closed (no detail): which one the worker
  // sees is a race between the two sides, and both say the same.
  CHECK(worker_log.count("the broker at " + keyed.endpoint()) >= 1);
  CHECK(worker_log.count("This worker has no keys, and the broker may require them: give it --key") ==
        worker_log.count("the broker at " + keyed.endpoint()));
  CHECK(worker_log.count("--broker-key and the broker's key") == 0);
  // And a worker with keys at a broker without any.
  LogCapture keyed_log;
  BrokerConfig open = test_broker_config(1);
  Broker plain(open, [](const std::string&) {});
  WorkerConfig c = thread_worker_config(plain.endpoint(), "alice");
  c.key_file = keys.file("allow/alice.key");
  c.broker_key_file = keys.file("broker.pub");
  {
    ThreadWorker alice(c, nullptr, keyed_log.sink());
    Serving serving(plain, 1.0);
  }
  CHECK(keyed_log.count("a broker logs its key, or that it has none") >= 1);
  CHECK(keyed_log.count("are keys configured on both sides") == 0);
}

TEST_CASE("admission: keys on one side only: a broker left waiting says, after a liveness period, what keys it needs") {
  // The worker may win the race in the handshake and be the only side to log
  // it: the broker waited for workers and said nothing more.
  Keys keys;
  const std::string silent = "still no worker after 500 ms, though ";
  auto wait_out = [](Broker& broker) {
    CHECK_THROWS_WITH(broker.run(tiny_job(), deadline(1.5)), "farm test deadline passed");
  };
  {  // keys on the broker only
    LogCapture log;
    Broker keyed(keys.keyed_config(), log.sink());
    ThreadWorker plain(thread_worker_config(keyed.endpoint(), "plain"));
    wait_out(keyed);
    CHECK(log.count(silent) == 1);  // once, not every turn
    CHECK(log.count("connection(s) reached " + keyed.endpoint() + ": a worker whose keys do not match this broker's") ==
          1);
    CHECK(log.count("This broker runs with CURVE keys: a worker needs --key (its .pub in the --allow folder) and "
                    "--broker-key holding this broker's public key " + keys.broker.public_key) == 1);
  }
  {  // keys on the worker only
    LogCapture log;
    Broker open(test_broker_config(1), log.sink());
    WorkerConfig c = thread_worker_config(open.endpoint(), "alice");
    c.key_file = keys.file("allow/alice.key");
    c.broker_key_file = keys.file("broker.pub");
    ThreadWorker alice(c);
    wait_out(open);
    CHECK(log.count(silent) == 1);
    CHECK(log.count("This broker runs without keys: a worker must have neither --key nor --broker-key") == 1);
  }
  {  // nobody at all: not a question of keys
    LogCapture log;
    Broker lonely(test_broker_config(1), log.sink());
    wait_out(lonely);
    CHECK(log.count("still no worker after 500 ms, and none connected to " + lonely.endpoint() +
                    ": are the workers started, with --connect naming this host and port?") == 1);
    CHECK(log.count("handshake") == 0);
  }
}

TEST_CASE("admission: a broker whose only worker was lost says its connection is still open, or that it spoke unregistered") {
  // A worker paused (SIGSTOP) and lost keeps its connection, and on SIGCONT
  // its heartbeat there is rejected as from an unregistered peer: the broker
  // said "none connected to ...: are the workers started?" all the same.
  zmq::context_t ctx;
  auto wait_until = [](LogCapture& log, const std::string& needle) {
    for (int i = 0; i < 500 && log.count(needle) == 0; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(10));
    REQUIRE(log.count(needle) == 1);
  };
  for (const bool speaks_when_lost : {false, true}) {
    CAPTURE(speaks_when_lost);
    LogCapture log;
    Broker broker(test_broker_config(1), log.sink());
    std::thread farm([&] { CHECK_THROWS_WITH(broker.run(tiny_job(), deadline(3)), "farm test deadline passed"); });
    {
      RawPeer paused(ctx, broker.endpoint());
      paused.join("paused", 1);
      paused.alive = false;  // silent from now on, as if stopped
      wait_until(log, "worker paused#1 silent for");
      if (speaks_when_lost) {
        paused.send_message(Heartbeat{0});  // resumed
        CHECK(paused.wait_for<Reregister>(2));
      }
      wait_until(log, "still no worker after 500 ms");
    }
    farm.join();
    CHECK(log.count("none connected") == 0);
    if (speaks_when_lost)
      CHECK(log.count("still no worker after 500 ms, though 1 message(s) came from unregistered peers (a lost worker "
                      "back on its old connection, e.g. resumed after a pause): each was told to re-register") == 1);
    else
      CHECK(log.count("still no worker after 500 ms; 1 connection(s) to " + broker.endpoint() +
                      " are still open but silent (a lost worker paused or stalled keeps its connection; it "
                      "re-registers when it resumes)") == 1);
  }
}

TEST_CASE("admission: results and heartbeats count only from the key that registered") {
  Keys keys;
  LogCapture log;
  BrokerConfig cfg = keys.keyed_config();
  cfg.liveness = 40;  // 4 s: alice's registration outlives the hijack attempt, even on a loaded machine
  Broker broker(cfg, log.sink());
  const FarmJob job = tiny_job();
  std::optional<FarmResult> result;
  std::thread farm([&] { result = broker.run(job, deadline(30)); });

  zmq::context_t ctx(1);
  TaskAssign task;
  {
    RawPeer alice(ctx, broker.endpoint(), keys.client(keys.alice, "w1"));
    alice.join("alice", 1);
    auto t = alice.wait_for<TaskAssign>(5);
    REQUIRE(t);
    task = *t;
  }  // alice's connection closes; her registration and task stay until she is lost
  // Bob, also invited, takes over alice's routing id and returns magenta for her task.
  // The broker's ROUTER frees that id only once it has seen alice's connection
  // close; a connection under it before then is refused, so bob tries again.
  TaskResult magenta = result_for(task, job.settings.width);
  for (int i = 0; i < (task.y1 - task.y0) * job.settings.width; ++i) magenta.rgb.insert(magenta.rgb.end(), {1, 0, 1});
  const std::string judged = "'result' for alice#1 from a connection with another key";
  for (int attempt = 0; attempt < 10 && log.count(judged) == 0; ++attempt) {
    RawPeer bob(ctx, broker.endpoint(), keys.client(keys.bob, "w1"));
    bob.send_message(magenta);
    bob.send_message(Ready{"bob-as-alice", 1e6, 1, 64, 100, 1.0});
    bob.idle(0.3);
  }
  ThreadWorker carol([&] {
    WorkerConfig c = thread_worker_config(broker.endpoint(), "bob");
    c.key_file = keys.file("allow/bob.key");
    c.broker_key_file = keys.file("broker.pub");
    return c;
  }());
  farm.join();
  REQUIRE(result);
  CHECK(result->rgb == in_process(job));  // no magenta
  CHECK(log.count(judged) == 1);
  CHECK(log.count("'ready' for alice#1 from a connection with another key") == 1);
}

TEST_CASE("admission: without keys only loopback peers are admitted, unless insecure") {
  const std::string outside = test::non_loopback_ipv4();
  if (outside.empty()) {
    MESSAGE("no non-loopback IPv4 address on this machine; skipped");
    return;
  }
  for (bool insecure : {false, true}) {
    CAPTURE(insecure);
    LogCapture log;
    BrokerConfig cfg = test_broker_config(1);
    cfg.bind = "tcp://*:*";
    cfg.insecure = insecure;
    Broker broker(cfg, log.sink());
    CHECK(log.count(insecure ? "WARNING: --insecure" : "WARNING: no --key/--allow") == 1);
    const std::string port = std::to_string(endpoint_port(broker.endpoint()));
    zmq::context_t ctx(1);
    RawPeer local(ctx, "tcp://127.0.0.1:" + port), remote(ctx, "tcp://" + outside + ":" + port);
    {
      Serving serving(broker, 1.5);
      local.send_message(Ready{"local", 21.0, 1, 2, 100, 1.0});
      remote.send_message(Ready{"remote", 21.0, 1, 2, 100, 1.0});
      CHECK(local.wait_for<Welcome>(1.0).has_value());
      CHECK(remote.wait_for<Welcome>(0.3).has_value() == insecure);
    }
    // Serials follow arrival order, which the two connections do not fix.
    auto registered = [&](const std::string& name) {
      return log.count("worker " + name + "#1 registered") + log.count("worker " + name + "#2 registered");
    };
    CHECK(registered("local") == 1);
    CHECK(registered("remote") == (insecure ? 1 : 0));
    CHECK(log.count("refused connection from " + outside + ": unauthenticated farm admits loopback peers only") ==
          (insecure ? 0 : 1));
  }
}

TEST_CASE("admission: a broker's text reaches a worker's log with control characters escaped") {
  zmq::context_t ctx(1);
  zmq::socket_t router(ctx, zmq::socket_type::router);
  router.bind("tcp://127.0.0.1:*");
  LogCapture log;
  ThreadWorker worker(thread_worker_config(router.get(zmq::sockopt::last_endpoint), "w"), nullptr, log.sink());
  std::string identity;
  zmq::pollitem_t item{router.handle(), 0, ZMQ_POLLIN, 0};
  zmq::poll(&item, 1, std::chrono::milliseconds(5000));
  REQUIRE(receive(router, &identity).has_value());  // its ready
  // A type no broker sends, whose name the worker's rejection quotes: raw, it
  // would end the line and forge one of its own.
  REQUIRE(protocol::send(router, Frames{R"({"v": 4, "type": "x\nrayfarm worker w: registered\u001b[2J"})"}, &identity));
  const auto start = Clock::now();
  while (log.count("rejected message from broker") == 0 && Clock::now() - start < std::chrono::seconds(5))
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  CHECK(log.count("x\\nrayfarm worker w: registered\\x1b[2J") == 1);
  std::lock_guard<std::mutex> lock(log.mutex);
  for (const std::string& line : log.lines)
    CHECK(line.find_first_of("\n\r\x1b") == std::string::npos);
}

TEST_CASE("admission: a peer's bytes that are not UTF-8 reach the broker's log escaped, not raw") {
  // The JSON parse error quotes what it read: raw, journald showed the line
  // as "[blob data]", and a peer could hide its own rejection that way.
  LogCapture log;
  Broker broker(test_broker_config(0), log.sink());
  zmq::context_t ctx(1);
  RawPeer peer(ctx, broker.endpoint());
  peer.send_frames({"\xff\xfe"});
  for (int i = 0; i < 100 && log.count("rejected message from unknown peer") == 0; ++i) broker.serve_for(0.02);
  CHECK(log.count("rejected message from unknown peer") == 1);
  CHECK(log.count("last read: '\\xff'") == 1);
  std::lock_guard<std::mutex> lock(log.mutex);
  for (const std::string& line : log.lines) CHECK_NOTHROW(nlohmann::json(line).dump());  // throws on non-UTF-8
}

TEST_CASE("admission: a worker's name and failure reason reach the log with control characters escaped") {
  LogCapture log;
  Broker broker(test_broker_config(1), log.sink());
  const FarmJob job = tiny_job();
  std::optional<FarmResult> result;
  std::thread farm([&] { result = broker.run(job, deadline(30)); });
  zmq::context_t ctx(1);
  {
    // Text that, written raw, ends the line and forges one of its own, or
    // clears the terminal (ESC, and its C1 form U+009B).
    RawPeer mallory(ctx, broker.endpoint());
    const JobSpec spec = mallory.join("m\nrayfarm broker: worker x#9 registered\x1b[2J", 1);
    mallory.send_message(JobFailed{spec.job, FailureScope::worker, "no\r\nrayfarm broker: job done \xc2\x9b" "2J"});
    mallory.idle(0.3);
  }
  ThreadWorker honest(thread_worker_config(broker.endpoint(), "honest"));
  farm.join();
  REQUIRE(result);
  CHECK(log.count("worker m\\nrayfarm broker: worker x#9 registered\\x1b[2J#1 registered") == 1);
  CHECK(log.count("(worker): no\\r\\nrayfarm broker: job done \\u009b2J") == 1);
  std::lock_guard<std::mutex> lock(log.mutex);
  for (const std::string& line : log.lines)
    CHECK(line.find_first_of("\n\r\x1b") == std::string::npos);
}
