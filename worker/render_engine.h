// RenderEngine: a worker's load and render threads. The socket loop hands it
// jobs (parse the NFF text, build the BVH, once per scene hash and settings)
// and tasks (render rows, then sleep to emulate a slower machine if throttled)
// and it answers with typed events -- the protocol's `job_ready`, `result` and
// `job_failed`, or a task it skipped -- queued for the socket loop, which an
// inproc PAIR doorbell wakes. Nothing is encoded between the threads, so there
// is no second wire format to decode. Keeping the tracer off the socket thread
// is what lets heartbeats flow while every core renders; loading on a thread
// of its own, with two scenes kept, lets a job the broker announces early be
// parsed and built while the current job's tasks still render (the paper's
// per-server initialisation, hidden).
#pragma once

#include <condition_variable>
#include <deque>
#include <exception>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <variant>
#include <vector>

#include <zmq.hpp>

#include "protocol/messages.h"

namespace rayfarm {

// A task of a job the engine no longer has loaded (newer jobs were loaded in
// between): the socket loop re-registers so the broker requeues it.
struct SkippedTask {
  uint64_t job = 0;
  uint32_t task = 0;
};

// A task stopped in progress by clear(): nothing to send, the broker has requeued it.
struct AbandonedTask {
  uint64_t job = 0;
  uint32_t task = 0;
};

using EngineEvent =
    std::variant<protocol::JobReady, protocol::TaskResult, protocol::JobFailed, SkippedTask, AbandonedTask>;

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

  void load(const protocol::JobSpec& job);  // queued for the load thread (the last kLoaded queued only)
  void render(const protocol::TaskAssign& task);  // queued for the render thread
  // Forgets the queued tasks and stops the one in progress (the broker has
  // requeued them all: an AbandonedTask event); loads stay.
  void clear();
  void clear(uint64_t job);  // forget the queued tasks of one job (it failed)

  std::vector<EngineEvent> take_events();  // everything finished since the last call

  // Scenes (with their BVHs) kept loaded: the current job's and the next's.
  static constexpr size_t kLoaded = 2;

 private:
  static constexpr size_t kJobsPerScene = 8;  // job ids remembered for one loaded scene
  struct Loaded;  // a scene and its BVH, and the jobs that use it
  struct Rendering;  // sets rendering_ for the length of a task

  template <class Item>
  void serve(std::deque<Item>& queue, EngineEvent (RenderEngine::*work)(const Item&));
  EngineEvent do_load(const protocol::JobSpec& job);
  EngineEvent do_render(const protocol::TaskAssign& task);
  EngineEvent failure(uint64_t job, const std::exception& e);
  std::shared_ptr<const Loaded> loaded_for(uint64_t job);
  void forget(uint64_t job);
  void post(EngineEvent event);
  void sleep_interruptible(double seconds);
  bool dropping();

  int threads_;
  double throttle_;
  std::string max_isa_;

  std::mutex mutex_;  // guards everything below but the threads
  std::condition_variable wake_;
  std::deque<protocol::JobSpec> loads_;
  std::deque<protocol::TaskAssign> tasks_;
  std::vector<EngineEvent> events_;
  zmq::socket_t doorbell_;  // rung by both threads, under mutex_
  bool stop_ = false;
  // The scenes of the last kLoaded loads, most recent last. Shared pointers:
  // a task renders on while a newer load evicts its scene.
  std::deque<std::shared_ptr<Loaded>> loaded_;
  std::shared_ptr<const Loaded> rendering_;  // the scene of the task in progress, abandoned on destruction
  bool dropping_ = false;  // clear() stopped the task in progress

  std::thread load_thread_, render_thread_;  // started last in the constructor
};

}  // namespace rayfarm
