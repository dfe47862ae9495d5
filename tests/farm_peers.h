// Farm test fixtures shared by the farm, local farm, admission and job failure
// tests: a small job and its in-process image, a log collector,
// small-heartbeat broker and worker configs, a Worker on its own thread, and a
// hand-driven DEALER peer speaking RFP for cases a real worker never produces.
#pragma once

#include <arpa/inet.h>
#include <ifaddrs.h>
#include <netinet/in.h>

#include <atomic>
#include <chrono>
#include <cstring>
#include <deque>
#include <functional>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <doctest/doctest.h>

#include "broker/broker.h"
#include "broker/child_process.h"
#include "protocol/transport.h"
#include "tests/test_paths.h"
#include "tracer/nff_reader.h"
#include "tracer/renderer.h"
#include "tracer/text_file.h"
#include "worker/worker.h"
#include "worker/worker_config.h"

namespace rayfarm::test {

using Clock = std::chrono::steady_clock;
using namespace rayfarm::protocol;

// Settings small enough for a farm case to take a second or so.
inline RenderSettings small_settings(int width = 64, int height = 64, int spp = 4) {
  RenderSettings s;
  s.width = width;
  s.height = height;
  s.spp = spp;
  s.max_depth = 5;
  s.seed = 7;
  s.threads = 1;
  return s;
}

// SPD balls-2 (91 spheres, reflective) at small_settings().
inline FarmJob small_job(int width = 64, int height = 64, int spp = 4) {
  return {read_text_file(spd_data("balls-2")), "balls-2.nff", small_settings(width, height, spp)};
}

// The image `job` renders in this process: what every farm must give, bit for bit.
inline std::vector<float> in_process(const FarmJob& job) {
  std::vector<float> rgb;
  Renderer(parse_nff(job.scene_text, job.scene_name), job.settings).render_rows(0, job.settings.height, rgb);
  return rgb;
}

// Bit for bit, so that -0 against 0 or two NaNs would not pass as equal or fail as unequal.
inline bool identical(const std::vector<float>& a, const std::vector<float>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0;
}

// Collects log lines from brokers and workers running on several threads.
struct LogCapture {
  std::mutex mutex;
  std::vector<std::string> lines;
  LogSink sink() {
    return [this](const std::string& line) {
      std::lock_guard<std::mutex> lock(mutex);
      lines.push_back(line);
    };
  }
  int count(const std::string& needle) {
    std::lock_guard<std::mutex> lock(mutex);
    int n = 0;
    for (const auto& l : lines) n += l.find(needle) != std::string::npos;
    return n;
  }
};

// A result for task `t` of an image `width` wide, pixels still to be filled in.
inline TaskResult result_for(const TaskAssign& t, int width) {
  TaskResult r;
  r.job = t.job;
  r.task = t.task;
  r.attempt = t.attempt;
  r.y0 = t.y0;
  r.y1 = t.y1;
  r.x0 = t.x0;
  r.x1 = t.x1;
  r.width = width;
  return r;
}

inline BrokerConfig test_broker_config(int min_workers) {
  BrokerConfig c;
  c.bind = "tcp://127.0.0.1:*";
  c.announce_bind = "tcp://127.0.0.1:*";
  c.heartbeat_ms = 100;
  c.liveness = 5;  // 0.5 s: generous enough for a loaded 2-core test machine
  c.min_workers = min_workers;
  c.progress = false;
  return c;
}

// The same with weight-sized tasks handed out in order (no backups), for
// tests of requeues, verdicts and fairness whose expectations need a fixed order.
inline BrokerConfig ordered_broker_config(int min_workers) {
  BrokerConfig c = test_broker_config(min_workers);
  c.policy = PolicyKind::weighted;
  return c;
}

// A watcher that aborts the job after `seconds`, then calls `also`.
inline std::function<void(const FarmProgress&)> deadline(double seconds,
                                                         std::function<void(const FarmProgress&)> also = {}) {
  const auto end = Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
  return [end, also](const FarmProgress& p) {
    if (Clock::now() > end) throw std::runtime_error("farm test deadline passed");
    if (also) also(p);
  };
}

inline ChildProcess spawn_worker(const std::string& endpoint, const std::string& name,
                                 std::vector<std::string> extra = {}) {
  std::vector<std::string> args = {"worker",    "--connect", endpoint,       "--name", name, "--threads", "1",
                                   "--heartbeat-ms", "100",  "--liveness",   "5",      "--quiet"};
  args.insert(args.end(), extra.begin(), extra.end());
  return ChildProcess(test::rayfarm_exe(), args);
}

inline const nlohmann::json& worker_entry(const nlohmann::json& record, const std::string& name) {
  for (const auto& w : record["workers"])
    if (w["name"] == name) return w;
  FAIL("no worker " << name << " in the job record");
  static nlohmann::json none;
  return none;
}

inline WorkerConfig thread_worker_config(const std::string& endpoint, const std::string& name) {
  WorkerConfig c;
  c.connect = endpoint;
  c.name = name;
  c.threads = 1;
  c.heartbeat_ms = 100;
  c.liveness = 5;
  c.reconnect_initial_ms = 100;
  c.reconnect_max_ms = 400;
  c.quiet = true;
  return c;
}

// A Worker on its own thread; stopped (bye) and joined on destruction.
struct ThreadWorker {
  std::atomic<bool> stop{false};
  std::atomic<bool> exited{false};  // run() returned, on its own or stopped
  int code = -1;
  std::thread thread;
  ThreadWorker(WorkerConfig c, zmq::context_t* ctx = nullptr, LogSink log = {})
      : thread([this, c, ctx, log] {
          Worker w(c, log ? log : [](const std::string&) {}, ctx);
          code = w.run(stop);
          exited = true;
        }) {}
  // Stops it (if it has not stopped on its own) and waits: run()'s status.
  int finish() {
    stop = true;
    if (thread.joinable()) thread.join();
    return code;
  }
  ~ThreadWorker() { finish(); }
};

// A hand-driven DEALER speaking RFP/1, for cases a real worker never produces.
struct RawPeer {
  zmq::socket_t socket;
  std::deque<Message> inbox;
  bool alive = true;  // sends heartbeats while waiting
  Clock::time_point last_beat;

  // `setup` runs before connecting (CURVE keys, a chosen routing id).
  RawPeer(zmq::context_t& ctx, const std::string& endpoint, const std::function<void(zmq::socket_t&)>& setup = {})
      : socket(ctx, zmq::socket_type::dealer) {
    configure_socket(socket, kMaxBrokerFrameBytes);
    if (setup) setup(socket);
    socket.connect(endpoint);
  }
  void send_message(const Message& m) { REQUIRE(protocol::send(socket, m)); }
  void send_frames(const Frames& f) { REQUIRE(protocol::send(socket, f)); }

  // Receives for up to `seconds`; returns the first message matching `want`,
  // keeping others (except heartbeats) in the inbox.
  template <class T> std::optional<T> wait_for(double seconds) {
    for (auto it = inbox.begin(); it != inbox.end(); ++it)
      if (auto* m = std::get_if<T>(&*it)) {
        T out = *m;
        inbox.erase(it);
        return out;
      }
    const auto end = Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
    while (Clock::now() < end) {
      if (alive && Clock::now() - last_beat > std::chrono::milliseconds(50)) {
        protocol::send(socket, Message{Heartbeat{0}});
        last_beat = Clock::now();
      }
      zmq::pollitem_t item{socket.handle(), 0, ZMQ_POLLIN, 0};
      zmq::poll(&item, 1, std::chrono::milliseconds(20));
      while (auto frames = receive(socket)) {
        Message m = decode(*frames);
        if (auto* hit = std::get_if<T>(&m)) return *hit;
        if (!std::holds_alternative<Heartbeat>(m) || std::is_same_v<T, Heartbeat>) inbox.push_back(m);
      }
    }
    return std::nullopt;
  }
  // Keeps the connection alive (heartbeats) for `seconds`.
  void idle(double seconds) { wait_for<Bye>(seconds); }

  // Registers, fetches the current job and reports it loaded; returns it.
  JobSpec join(const std::string& name, int credit, double weight = 21.0) {
    send_message(Ready{name, weight, 1, credit, 100, 1.0});
    auto welcome = wait_for<Welcome>(5);
    REQUIRE(welcome);
    uint64_t job = welcome->job;
    while (job == 0) {
      auto hb = wait_for<Heartbeat>(5);
      REQUIRE(hb);
      job = hb->job;
    }
    send_message(FetchJob{job});
    auto spec = wait_for<JobSpec>(5);
    REQUIRE(spec);
    send_message(JobReady{spec->job, 0});
    return *spec;
  }
};

// A ROUTER driven by hand: a broker that sends a real worker what no rayfarm
// broker does. It heartbeats while it listens, so the worker stays registered.
struct HandBroker {
  zmq::context_t ctx{1};
  zmq::socket_t router{ctx, zmq::socket_type::router};
  std::string endpoint;
  std::string identity;  // the worker's, from its first message

  HandBroker() {
    router.set(zmq::sockopt::linger, 0);
    router.bind("tcp://127.0.0.1:*");
    endpoint = router.get(zmq::sockopt::last_endpoint);
  }
  void send_message(const Message& m) { REQUIRE(protocol::send(router, m, &identity)); }

  // The worker's messages for `seconds` (heartbeats left out), or until one
  // of type T has come, which is then the last.
  template <class T = Bye> std::vector<Message> listen(double seconds) {
    std::vector<Message> heard;
    const auto end = Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
    auto beat = Clock::now();
    while (Clock::now() < end) {
      zmq::pollitem_t item{router.handle(), 0, ZMQ_POLLIN, 0};
      zmq::poll(&item, 1, std::chrono::milliseconds(20));
      while (auto frames = receive(router, &identity)) {
        Message m = decode(*frames);
        if (std::holds_alternative<Heartbeat>(m)) continue;
        heard.push_back(m);
        if (std::holds_alternative<T>(m)) return heard;
      }
      if (!identity.empty() && Clock::now() - beat > std::chrono::milliseconds(50)) {
        protocol::send(router, Message{Heartbeat{0}}, &identity);
        beat = Clock::now();
      }
    }
    return heard;
  }
  template <class T> std::optional<T> wait_for(double seconds) {
    auto heard = listen<T>(seconds);
    if (heard.empty() || !std::holds_alternative<T>(heard.back())) return std::nullopt;
    return std::get<T>(heard.back());
  }
  // Answers the worker's `ready` and hands it `job` (scene and settings), which it loads.
  void welcome_with(const FarmJob& job, uint64_t id) {
    REQUIRE(wait_for<Ready>(5));
    send_message(Welcome{100, 5, 1, 0});
    send_message(JobSpec{id, fnv1a64(job.scene_text), job.scene_name, job.settings, job.scene_text});
    REQUIRE(wait_for<JobReady>(10));
  }
};

// An IPv4 address of this machine that is not loopback ("" if none): a peer
// connecting to it is, to the broker, a peer from another machine.
inline std::string non_loopback_ipv4() {
  ifaddrs* list = nullptr;
  if (getifaddrs(&list) != 0) return "";
  std::string found;
  for (ifaddrs* i = list; i && found.empty(); i = i->ifa_next) {
    if (!i->ifa_addr || i->ifa_addr->sa_family != AF_INET) continue;
    char text[INET_ADDRSTRLEN];
    inet_ntop(AF_INET, &reinterpret_cast<sockaddr_in*>(i->ifa_addr)->sin_addr, text, sizeof text);
    if (std::string(text).rfind("127.", 0) != 0) found = text;
  }
  freeifaddrs(list);
  return found;
}

// Renders task t with `renderer`, as a worker would (rows, or a span of a row).
inline TaskResult render_task(const Renderer& renderer, const TaskAssign& t) {
  TaskResult r = result_for(t, renderer.settings().width);
  if (t.x0 == 0 && t.x1 == r.width)
    renderer.render_rows(t.y0, t.y1, r.rgb, &r.stats);
  else
    renderer.render_span(t.y0, t.x0, t.x1, r.rgb, &r.stats);
  return r;
}

// Runs a broker job on its own thread so the test thread can play workers.
struct BrokerThread {
  FarmResult result;
  std::string error;
  std::atomic<bool> finished{false};
  std::thread thread;
  BrokerThread(Broker& broker, const FarmJob& job, double deadline_s)
      : thread([this, &broker, job, deadline_s] {
          try {
            result = broker.run(job, deadline(deadline_s));
          } catch (const std::exception& e) {
            error = e.what();
          }
          finished = true;
        }) {}
  void join() {
    if (thread.joinable()) thread.join();
  }
  ~BrokerThread() { join(); }
};

}  // namespace rayfarm::test
