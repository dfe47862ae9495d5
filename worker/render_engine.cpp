// The worker's load and render threads; see render_engine.h.
#include "worker/render_engine.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <utility>

#include "protocol/transport.h"
#include "tracer/elapsed.h"
#include "tracer/error.h"
#include "tracer/log_text.h"
#include "tracer/nff_reader.h"
#include "tracer/renderer.h"
#include "tracer/scene.h"
#include "tracer/text_file.h"

namespace rayfarm {
namespace {

using Clock = std::chrono::steady_clock;

// A double in full precision (std::to_string keeps six decimals, which would
// let a cutoff of 1e-7 reuse the renderer built for 2e-7).
std::string exact(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%.17g", v);
  return text;
}

// Everything that decides whether a built Renderer can be reused.
std::string cache_key(const protocol::JobSpec& j) {
  const RenderSettings& s = j.settings;
  return protocol::hash_hex(j.scene_hash) + "/" + std::to_string(s.width) + "x" + std::to_string(s.height) + "/" +
         std::to_string(s.spp) + "/" + std::to_string(s.max_depth) + "/" + std::to_string(s.seed) + "/" +
         exact(s.adaptive_contrast) + "/" + exact(s.cutoff) + "/" +
         (s.robust_bvh ? "robust" : "fast");
}

// What is wrong with the size of `task`'s result, empty when nothing is: a
// result frame carries at most kMaxResultBytes (protocol/SPEC.md, "Result
// frame"), which no task of the broker's (at most max_task_rows rows) exceeds.
std::string result_size_problem(const protocol::TaskAssign& task) {
  const uint64_t bytes = protocol::result_frame_bytes(task.x1 - task.x0, task.y1 - task.y0);
  if (bytes <= protocol::kMaxResultBytes) return {};
  return "rows [" + std::to_string(task.y0) + ", " + std::to_string(task.y1) + ") of pixels [" +
         std::to_string(task.x0) + ", " + std::to_string(task.x1) + ") make a result of " +
         std::to_string((bytes + (1u << 20) - 1) >> 20) + " MiB, more than the " +
         std::to_string(protocol::kMaxResultBytes >> 20) + " MiB a result frame may carry";
}

// A reason the protocol can carry (kMaxReasonBytes, UTF-8). A parse error
// starts with the scene's name, which may itself be 4096 bytes: the broker
// refused a longer `job_failed` as malformed and never failed the job, while
// this worker had dropped it. The start and the end (line and message) are
// kept. It quotes the scene's text as written, which need not be UTF-8 (a
// Latin-1 "sc\xe8ne" where a keyword goes): such a byte is sent as U+FFFD.
std::string fit_reason(const std::string& reason) {
  return middle_excerpt(valid_utf8(reason), protocol::kMaxReasonBytes, 1024);
}

}  // namespace

struct RenderEngine::Loaded {
  std::string key;
  std::vector<uint64_t> jobs;  // the last few jobs of this scene and settings
  std::unique_ptr<Scene> scene;
  std::unique_ptr<Renderer> renderer;
};

RenderEngine::RenderEngine(zmq::context_t& context, std::string endpoint, int threads, double throttle,
                           std::string max_isa)
    : threads_(threads), throttle_(throttle), max_isa_(std::move(max_isa)), doorbell_(context, zmq::socket_type::pair) {
  // Created here, not on a worker thread, so running out of sockets is an
  // exception in the constructor's caller rather than a terminate() there.
  doorbell_.set(zmq::sockopt::linger, 0);
  doorbell_.connect(endpoint);
  load_thread_ = std::thread([this] { serve(loads_, &RenderEngine::do_load); });
  render_thread_ = std::thread([this] { serve(tasks_, &RenderEngine::do_render); });
}

RenderEngine::~RenderEngine() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
    tasks_.clear();
    loads_.clear();
    // Its result would not be sent: the task in progress stops now, not
    // after the minutes a large one may take (the worker said it stops).
    if (rendering_) rendering_->renderer->abandon();
  }
  wake_.notify_all();
  load_thread_.join();
  render_thread_.join();
}

void RenderEngine::load(const protocol::JobSpec& job) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    loads_.push_back(job);
    // Only the last kLoaded loads stay resident, so an older one still queued
    // would only be evicted by those after it; and each holds its scene text
    // (up to 256 MiB). A broker announcing job after job queued them all. The
    // broker names its current job in every heartbeat: a job dropped here
    // that it still wants is fetched again.
    while (loads_.size() > kLoaded) loads_.pop_front();
  }
  wake_.notify_all();
}

void RenderEngine::render(const protocol::TaskAssign& task) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    tasks_.push_back(task);
  }
  wake_.notify_all();
}

void RenderEngine::clear() {
  // Tasks only: a load still answers, the socket loop counts on it. The task
  // in progress stops too: after a broker restart it rendered on for the
  // minutes a large one takes, for a result no one would take, while the new
  // registration's tasks waited behind it.
  {
    std::lock_guard<std::mutex> lock(mutex_);
    tasks_.clear();
    if (rendering_) {
      dropping_ = true;
      rendering_->renderer->abandon();
    }
  }
  wake_.notify_all();  // a throttled task's sleep ends too
}

void RenderEngine::clear(uint64_t job) {
  std::lock_guard<std::mutex> lock(mutex_);
  tasks_.erase(std::remove_if(tasks_.begin(), tasks_.end(), [&](const auto& t) { return t.job == job; }), tasks_.end());
}

std::vector<EngineEvent> RenderEngine::take_events() {
  std::lock_guard<std::mutex> lock(mutex_);
  return std::exchange(events_, {});
}

void RenderEngine::post(EngineEvent event) {
  std::lock_guard<std::mutex> lock(mutex_);
  events_.push_back(std::move(event));
  // A full doorbell queue means a ring is already pending: never block on it.
  try {
    (void)doorbell_.send(zmq::const_buffer("", 0), zmq::send_flags::dontwait);
  } catch (const zmq::error_t&) {  // context shutting down: the socket loop is gone anyway
  }
}

// One thread's loop over its queue (loads or tasks): take the oldest, do it,
// post what came of it, failures included.
template <class Item>
void RenderEngine::serve(std::deque<Item>& queue, EngineEvent (RenderEngine::*work)(const Item&)) {
  while (true) {
    Item item;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait(lock, [&] { return stop_ || !queue.empty(); });
      if (stop_) return;
      item = std::move(queue.front());
      queue.pop_front();
    }
    EngineEvent event;
    try {
      event = (this->*work)(item);
    } catch (const std::exception& e) {
      event = failure(item.job, e);
    }
    post(std::move(event));
  }
}

// The scene's or settings' fault (InputError) fails the job on every worker;
// anything else (memory, the Embree device) is this machine's.
EngineEvent RenderEngine::failure(uint64_t job, const std::exception& e) {
  forget(job);
  const bool input = dynamic_cast<const InputError*>(&e) != nullptr;
  return protocol::JobFailed{job, input ? protocol::FailureScope::job : protocol::FailureScope::worker,
                             fit_reason(e.what())};
}

void RenderEngine::forget(uint64_t job) {
  std::lock_guard<std::mutex> lock(mutex_);
  loaded_.erase(std::remove_if(loaded_.begin(), loaded_.end(),
                               [&](const auto& l) {
                                 return std::find(l->jobs.begin(), l->jobs.end(), job) != l->jobs.end();
                               }),
                loaded_.end());
}

// Names the scene a task renders while it does, so the destructor can abandon that render.
struct RenderEngine::Rendering {
  RenderEngine& engine;
  Rendering(RenderEngine& e, std::shared_ptr<const Loaded> loaded) : engine(e) {
    std::lock_guard<std::mutex> lock(engine.mutex_);
    engine.rendering_ = std::move(loaded);
    engine.dropping_ = false;
    engine.rendering_->renderer->resume();  // a task clear() stopped may have been its scene's last
    if (engine.stop_) engine.rendering_->renderer->abandon();  // stopped between taking the task and here
  }
  ~Rendering() {
    std::lock_guard<std::mutex> lock(engine.mutex_);
    engine.rendering_.reset();
  }
};

std::shared_ptr<const RenderEngine::Loaded> RenderEngine::loaded_for(uint64_t job) {
  std::lock_guard<std::mutex> lock(mutex_);
  for (const auto& l : loaded_)
    if (std::find(l->jobs.begin(), l->jobs.end(), job) != l->jobs.end()) return l;
  return nullptr;
}

// Runs on the load thread; the parse and BVH build happen outside the lock.
EngineEvent RenderEngine::do_load(const protocol::JobSpec& job) {
  const std::string key = cache_key(job);
  double init_s = 0;
  std::unique_lock<std::mutex> lock(mutex_);
  auto same = std::find_if(loaded_.begin(), loaded_.end(), [&](const auto& l) { return l->key == key; });
  std::shared_ptr<Loaded> l;
  if (same != loaded_.end()) {  // reuse, and make it the most recent
    l = *same;
    loaded_.erase(same);
  } else {
    if (loaded_.size() >= kLoaded) loaded_.pop_front();  // before building: at most kLoaded BVHs resident
    lock.unlock();
    const auto t0 = Clock::now();
    l = std::make_shared<Loaded>();
    l->key = key;
    l->scene = std::make_unique<Scene>(parse_nff(job.scene_text, job.scene_name));
    RenderSettings settings = job.settings;
    settings.threads = threads_;
    settings.max_isa = max_isa_;
    l->renderer = std::make_unique<Renderer>(*l->scene, settings);
    init_s = seconds_since(t0);
    lock.lock();
  }
  l->jobs.push_back(job.job);
  if (l->jobs.size() > kJobsPerScene) l->jobs.erase(l->jobs.begin());  // a scene reused by job after job
  loaded_.push_back(std::move(l));
  return protocol::JobReady{job.job, init_s};
}

EngineEvent RenderEngine::do_render(const protocol::TaskAssign& task) {
  const auto loaded = loaded_for(task.job);
  if (!loaded) return SkippedTask{task.job, task.task};
  const Rendering rendering(*this, loaded);
  protocol::TaskResult r;
  r.job = task.job;
  r.task = task.task;
  r.attempt = task.attempt;
  r.y0 = task.y0;
  r.y1 = task.y1;
  r.x0 = task.x0;
  r.x1 = task.x1;
  r.width = loaded->renderer->settings().width;
  // A task the job cannot have (the broker's fault) fails the job with the reason.
  const std::string bad = protocol::pixel_band_problem(task.y0, task.y1, task.x0, task.x1, r.width);
  if (!bad.empty()) throw InputError("task " + std::to_string(task.task) + ": " + bad);
  // Checked before the pixels are allocated: the broker could never take such
  // a result (it would have cost gigabytes here and minutes of rendering first).
  if (const std::string big = result_size_problem(task); !big.empty())
    throw InputError("task " + std::to_string(task.task) + ": " + big);
  const auto t0 = Clock::now();
  try {
    if (task.x0 == 0 && task.x1 == r.width)
      loaded->renderer->render_rows(task.y0, task.y1, r.rgb, &r.stats);
    else
      loaded->renderer->render_span(task.y0, task.x0, task.x1, r.rgb, &r.stats);
  } catch (const RenderAbandoned&) {
    if (dropping()) return AbandonedTask{task.job, task.task};
    throw;  // the engine stops
  }
  r.render_s = seconds_since(t0);
  if (throttle_ > 1) {
    const auto t1 = Clock::now();
    sleep_interruptible((throttle_ - 1) * r.render_s);
    if (dropping()) return AbandonedTask{task.job, task.task};
    r.throttle_s = seconds_since(t1);
  }
  return r;
}

bool RenderEngine::dropping() {
  std::lock_guard<std::mutex> lock(mutex_);
  return dropping_;
}

void RenderEngine::sleep_interruptible(double seconds) {
  std::unique_lock<std::mutex> lock(mutex_);
  wake_.wait_for(lock, std::chrono::duration<double>(seconds), [&] { return stop_ || dropping_; });
}

}  // namespace rayfarm
