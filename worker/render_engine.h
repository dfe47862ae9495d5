// RenderEngine: a worker's render thread. The socket loop hands it jobs (parse
// the NFF text, build the BVH, once per scene hash and settings) and tasks
// (render rows, then sleep to emulate a slower machine if throttled); it answers
// with encoded `job_ready` / `result` messages on an inproc PAIR socket. Keeping
// the tracer off the socket thread is what lets heartbeats flow while every core
// renders.
#pragma once

#include <condition_variable>
#include <deque>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <variant>

#include <zmq.hpp>

#include "protocol/messages.h"

namespace rayfarm {

class Renderer;
struct Scene;

class RenderEngine {
 public:
  // `endpoint`: an inproc endpoint the caller has bound a PAIR socket to. A
  // fatal error (unparsable scene) arrives there as the frames {"!error", text},
  // a task of a job no longer loaded as {"!skipped", task id}.
  // `max_isa` caps Embree's kernel width (EmbreeOptions::max_isa): pixels do
  // not depend on it, so a farm test can mix widths.
  RenderEngine(zmq::context_t& context, std::string endpoint, int threads, double throttle,
               std::string max_isa = "");
  ~RenderEngine();
  RenderEngine(const RenderEngine&) = delete;
  RenderEngine& operator=(const RenderEngine&) = delete;

  void load(const protocol::JobSpec& job);
  void render(const protocol::TaskAssign& task);
  void clear();  // forget queued tasks (the broker has requeued them); loads stay

 private:
  using Command = std::variant<protocol::JobSpec, protocol::TaskAssign>;
  void loop();
  void do_load(zmq::socket_t& out, const protocol::JobSpec& job);
  void do_render(zmq::socket_t& out, const protocol::TaskAssign& task);
  void sleep_interruptible(double seconds);

  zmq::context_t& context_;
  std::string endpoint_;
  int threads_;
  double throttle_;
  std::string max_isa_;

  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<Command> queue_;
  bool stop_ = false;

  // Render-thread state: the scene and BVH of the last job, keyed by content.
  std::string cache_key_;
  uint64_t loaded_job_ = 0;
  std::unique_ptr<Scene> scene_;
  std::unique_ptr<Renderer> renderer_;

  std::thread thread_;  // last: starts after everything above exists
};

}  // namespace rayfarm
