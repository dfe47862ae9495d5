// RenderEngine: a worker's render thread. The socket loop hands it jobs (parse
// the NFF text, build the BVH, once per scene hash and settings) and tasks
// (render rows, then sleep to emulate a slower machine if throttled) and
// answers with typed events -- the protocol's `job_ready`, `result` and
// `job_failed`, or a task it skipped -- queued for the socket loop, which an
// inproc PAIR doorbell wakes. Nothing is encoded between the two threads, so
// there is no second wire format to decode. Keeping the tracer off the socket
// thread is what lets heartbeats flow while every core renders.
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

class Renderer;
struct Scene;

// A task of a job the render thread no longer has loaded (a newer job was
// loaded in between): the socket loop re-registers so the broker requeues it.
struct SkippedTask {
  uint64_t job = 0;
  uint32_t task = 0;
};

using EngineEvent = std::variant<protocol::JobReady, protocol::TaskResult, protocol::JobFailed, SkippedTask>;

class RenderEngine {
 public:
  // `endpoint`: an inproc endpoint the caller has bound a PAIR socket to; a
  // one-byte frame arrives there whenever events are waiting (take_events).
  // A job that fails to load or render becomes a JobFailed event: the scene's
  // or settings' fault (InputError) has scope `job`, anything else `worker`.
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

  std::vector<EngineEvent> take_events();  // everything finished since the last call

 private:
  using Command = std::variant<protocol::JobSpec, protocol::TaskAssign>;
  void loop();
  EngineEvent do_load(const protocol::JobSpec& job);
  EngineEvent do_render(const protocol::TaskAssign& task);
  void sleep_interruptible(double seconds);
  void forget_job();

  zmq::socket_t doorbell_;  // used by the render thread only, after construction
  int threads_;
  double throttle_;
  std::string max_isa_;

  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<Command> queue_;
  std::vector<EngineEvent> events_;
  bool stop_ = false;

  // Render-thread state: the scene and BVH of the last job, keyed by content.
  std::string cache_key_;
  uint64_t loaded_job_ = 0;
  std::unique_ptr<Scene> scene_;
  std::unique_ptr<Renderer> renderer_;

  std::thread thread_;  // started last in the constructor, after everything above exists
};

}  // namespace rayfarm
