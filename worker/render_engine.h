// RenderEngine: a worker's render and load threads. The socket loop hands it
// jobs (parse the NFF text, build the BVH, once per scene hash and settings)
// and tasks (render rows, then sleep to emulate a slower machine if throttled);
// it answers with encoded `job_ready` / `result` messages on an inproc PAIR
// socket. Keeping the tracer off the socket thread is what lets heartbeats
// flow while every core renders. Loading runs on its own thread and two scenes
// stay loaded, so a job the broker announces early is parsed and built while
// the tasks of the current one are still rendering (the paper's per-server
// initialisation, hidden).
#pragma once

#include <condition_variable>
#include <deque>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <variant>
#include <vector>

#include <zmq.hpp>

#include "protocol/messages.h"

namespace rayfarm {

class RenderEngine {
 public:
  // `endpoint`: an inproc endpoint the caller has bound a PAIR socket to. A
  // fatal error (unparsable scene) arrives there as the frames {"!error", text},
  // a task of a job no longer loaded as {"!skipped", task id}.
  RenderEngine(zmq::context_t& context, std::string endpoint, int threads, double throttle);
  ~RenderEngine();
  RenderEngine(const RenderEngine&) = delete;
  RenderEngine& operator=(const RenderEngine&) = delete;

  void load(const protocol::JobSpec& job);
  void render(const protocol::TaskAssign& task);
  void clear();  // forget queued tasks (the broker has requeued them); loads stay

 private:
  struct Loaded;  // a scene and its BVH, and the jobs that use it
  struct LoadDone {
    uint64_t job = 0;
    double init_s = 0;
  };
  struct LoadFailed {
    std::string what;
  };
  // The render thread's queue; the load thread puts its outcomes at the front
  // so `job_ready` leaves right after the task being rendered.
  using Command = std::variant<protocol::TaskAssign, LoadDone, LoadFailed>;

  void render_loop();
  void load_loop();
  double do_load(const protocol::JobSpec& job);
  void do_render(zmq::socket_t& out, const protocol::TaskAssign& task);
  std::shared_ptr<const Loaded> loaded_for(uint64_t job);
  void sleep_interruptible(double seconds);

  zmq::context_t& context_;
  std::string endpoint_;
  int threads_;
  double throttle_;

  std::mutex mutex_;  // guards everything below but the threads
  std::condition_variable wake_;
  std::deque<Command> queue_;
  std::deque<protocol::JobSpec> loads_;
  bool stop_ = false;
  // The scenes of the last kLoaded loads, most recent last. Shared pointers:
  // a task renders on while a newer load evicts its scene.
  static constexpr size_t kLoaded = 2;
  std::deque<std::shared_ptr<Loaded>> loaded_;

  std::thread render_thread_, load_thread_;  // last: start after everything above exists
};

}  // namespace rayfarm
