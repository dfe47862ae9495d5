// Broker capacity benchmark (`make bench-broker`): how many task dispatches per
// second one broker sustains, and how many workers it carries through a job.
// The workers are stand-ins: DEALER sockets in this process that speak RFP/1
// (register, fetch the job, report it loaded) and answer every task at once
// with black rows, so the broker's loop (sockets, codec, task board, dispatch
// policy) is all that is measured. Real sockets on 127.0.0.1. Prints numbers,
// never pass/fail; the last line is "broker capacity: N tasks/s; M workers".
#include <sys/resource.h>
#include <time.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>
#include <vector>

#include "broker/broker.h"
#include "protocol/transport.h"

using namespace rayfarm;
using namespace rayfarm::protocol;
using Clock = std::chrono::steady_clock;

namespace {

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// CPU seconds of the calling thread: the broker's own cost, whatever else the
// (shared) machine is doing.
double thread_cpu_s() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return t.tv_sec + t.tv_nsec * 1e-9;
}

// N stand-in workers on one thread, polled together.
class StandInWorkers {
 public:
  StandInWorkers(zmq::context_t& ctx, const std::string& endpoint, int count, int credit) {
    for (int i = 0; i < count; ++i) {
      sockets_.emplace_back(ctx, zmq::socket_type::dealer);
      configure_socket(sockets_.back(), kMaxBrokerFrameBytes);
      sockets_.back().connect(endpoint);
      send(sockets_.back(), Message{Ready{"stand-in-" + std::to_string(i), 21.0, 1, credit, 60000, 1.0}});
    }
    for (zmq::socket_t& s : sockets_) items_.push_back({s.handle(), 0, ZMQ_POLLIN, 0});
  }

  // Serves until `stop`; returns the tasks answered.
  long serve(const std::atomic<bool>& stop) {
    long answered = 0;
    while (!stop) {
      poll_interruptible(items_.data(), items_.size(), 20);
      for (size_t i = 0; i < items_.size(); ++i) {
        if (!(items_[i].revents & ZMQ_POLLIN)) continue;
        while (auto frames = receive(sockets_[i])) answered += answer(sockets_[i], decode(*frames));
      }
    }
    return answered;
  }

 private:
  int answer(zmq::socket_t& s, const Message& m) {
    if (auto* w = std::get_if<Welcome>(&m)) {
      if (w->job) send(s, Message{FetchJob{w->job}});
    } else if (auto* h = std::get_if<Heartbeat>(&m)) {
      if (h->job) send(s, Message{FetchJob{h->job}});
    } else if (auto* j = std::get_if<JobSpec>(&m)) {
      width_ = j->settings.width;
      send(s, Message{JobReady{j->job, 0}});
    } else if (auto* t = std::get_if<TaskAssign>(&m)) {
      TaskResult r;
      r.job = t->job;
      r.task = t->task;
      r.attempt = t->attempt;
      r.y0 = t->y0;
      r.y1 = t->y1;
      r.width = width_;
      r.render_s = 1e-6;
      r.rgb.assign(static_cast<size_t>(t->y1 - t->y0) * width_ * 3, 0.0f);
      send(s, Message{r});
      return 1;
    }
    return 0;
  }

  std::vector<zmq::socket_t> sockets_;
  std::vector<zmq::pollitem_t> items_;
  int width_ = 1;
};

struct Run {
  double seconds = 0, cpu_s = 0;  // the job's render_s; broker thread CPU over the whole run
  int tasks = 0, workers = 0;
  bool ok = false;
};

// One job of `height` one-pixel-wide rows on `workers` stand-ins.
Run run_job(int workers, int credit, int height, PolicyKind policy, double deadline_s) {
  BrokerConfig cfg;
  cfg.bind = "tcp://127.0.0.1:*";
  cfg.announce_bind = "tcp://127.0.0.1:*";
  cfg.min_workers = workers;
  cfg.heartbeat_ms = 60000;  // stand-ins send no heartbeats; results and readies prove them alive
  cfg.liveness = 10;
  cfg.progress = false;
  cfg.policy = policy;
  Broker broker(cfg, [](const std::string&) {});
  zmq::context_t ctx(1);
  ctx.set(zmq::ctxopt::max_sockets, workers + 16);
  StandInWorkers stand_ins(ctx, broker.endpoint(), workers, credit);
  std::atomic<bool> stop{false};
  std::thread serving([&] { stand_ins.serve(stop); });
  FarmJob job;
  job.scene_text = "# a scene the stand-ins never parse\n";
  job.scene_name = "capacity";
  job.settings.width = 1;
  job.settings.height = height;
  job.settings.spp = 1;
  Run run;
  run.workers = workers;
  const auto t0 = Clock::now();
  const double cpu0 = thread_cpu_s();
  try {
    const FarmResult r = broker.run(job, [&](const FarmProgress&) {
      if (seconds_since(t0) > deadline_s) throw std::runtime_error("deadline");
    });
    run.tasks = r.record["task_count"].get<int>();
    run.seconds = r.record["render_s"].get<double>();
    run.cpu_s = thread_cpu_s() - cpu0;
    run.ok = true;
  } catch (const std::exception& e) {
    std::printf("  %d workers: %s\n", workers, e.what());
  }
  stop = true;
  serving.join();
  return run;
}

// Each stand-in holds three descriptors (its socket's mailbox, its TCP end and
// the broker's): raise the soft limit as far as the hard one allows.
rlim_t raise_fd_limit() {
  rlimit l{};
  getrlimit(RLIMIT_NOFILE, &l);
  l.rlim_cur = l.rlim_max;
  setrlimit(RLIMIT_NOFILE, &l);
  getrlimit(RLIMIT_NOFILE, &l);
  return l.rlim_cur;
}

}  // namespace

int main(int argc, char** argv) {
  const int max_workers = argc > 1 ? std::atoi(argv[1]) : 4000;
  const rlim_t fds = raise_fd_limit();
  std::printf("# broker capacity (%u cores), open-file limit raised to %llu\n", std::thread::hardware_concurrency(),
              static_cast<unsigned long long>(fds));
  std::printf("## dispatch rate: a 65536-row image, 8 stand-in workers (median of 3 runs)\n");
  std::printf("## wall: tasks / render_s; cpu: tasks / broker-thread CPU seconds (the capacity of one free core)\n");
  double best_rate = 0;
  for (PolicyKind policy : {PolicyKind::paper, PolicyKind::weighted, PolicyKind::adaptive}) {
    std::vector<double> wall, cpu;
    int tasks = 0;
    for (int rep = 0; rep < 3; ++rep) {
      const Run r = run_job(8, policy == PolicyKind::paper ? 1 : 64, 65536, policy, 120);
      if (!r.ok || r.seconds <= 0 || r.cpu_s <= 0) continue;
      wall.push_back(r.tasks / r.seconds);
      cpu.push_back(r.tasks / r.cpu_s);
      tasks = r.tasks;
    }
    std::sort(wall.begin(), wall.end());
    std::sort(cpu.begin(), cpu.end());
    const double w = wall.empty() ? 0 : wall[wall.size() / 2], c = cpu.empty() ? 0 : cpu[cpu.size() / 2];
    std::printf("  policy %-8s (credit %2d, %5d tasks): wall %.0f tasks/s, cpu %.0f tasks/s\n", policy_name(policy),
                policy == PolicyKind::paper ? 1 : 64, tasks, w, c);
    if (policy != PolicyKind::weighted) continue;  // one-row tasks with credit: the dispatch rate proper
    best_rate = c;
  }
  std::printf("## workers carried through a job (adaptive, credit 2, 4 rows each)\n");
  int carried = 0;
  for (int n = 500; n <= max_workers; n *= 2) {
    const Run r = run_job(n, 2, std::min(65536, 4 * n), PolicyKind::adaptive, 120);
    std::printf("  %d workers: %s (%d tasks in %.2f s)\n", n, r.ok ? "finished" : "failed", r.tasks, r.seconds);
    if (!r.ok) break;
    carried = n;
  }
  std::printf("broker capacity: %.0f tasks/s (one-row tasks per broker CPU second); %d workers\n", best_rate, carried);
  return 0;
}
