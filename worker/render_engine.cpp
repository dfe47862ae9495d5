// The worker's render thread; see render_engine.h.
#include "worker/render_engine.h"

#include <algorithm>
#include <chrono>
#include <cstdio>

#include "protocol/transport.h"
#include "tracer/nff_reader.h"
#include "tracer/renderer.h"
#include "tracer/scene.h"

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

}  // namespace

struct RenderEngine::Loaded {
  std::string key;
  std::vector<uint64_t> jobs;  // the last few jobs of this scene and settings
  std::unique_ptr<Scene> scene;
  std::unique_ptr<Renderer> renderer;
};

RenderEngine::RenderEngine(zmq::context_t& context, std::string endpoint, int threads, double throttle)
    : context_(context), endpoint_(std::move(endpoint)), threads_(threads), throttle_(throttle),
      render_thread_([this] { render_loop(); }), load_thread_([this] { load_loop(); }) {}

RenderEngine::~RenderEngine() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
    queue_.clear();
    loads_.clear();
  }
  wake_.notify_all();
  render_thread_.join();
  load_thread_.join();
}

void RenderEngine::load(const protocol::JobSpec& job) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    loads_.push_back(job);
  }
  wake_.notify_all();
}

void RenderEngine::render(const protocol::TaskAssign& task) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    queue_.emplace_back(task);
  }
  wake_.notify_all();
}

void RenderEngine::clear() {
  // Tasks only: load outcomes stay, the socket loop counts on their answer.
  std::lock_guard<std::mutex> lock(mutex_);
  queue_.erase(std::remove_if(queue_.begin(), queue_.end(),
                              [](const Command& c) { return std::holds_alternative<protocol::TaskAssign>(c); }),
               queue_.end());
}

void RenderEngine::render_loop() {
  zmq::socket_t out(context_, zmq::socket_type::pair);
  out.set(zmq::sockopt::linger, 0);
  out.set(zmq::sockopt::sndtimeo, 2000);  // never wedge shutdown behind a full queue
  out.connect(endpoint_);
  while (true) {
    Command cmd;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait(lock, [&] { return stop_ || !queue_.empty(); });
      if (stop_) return;
      cmd = std::move(queue_.front());
      queue_.pop_front();
    }
    if (auto* done = std::get_if<LoadDone>(&cmd)) {
      protocol::send_waiting(out, protocol::encode(protocol::JobReady{done->job, done->init_s}));
    } else if (auto* failed = std::get_if<LoadFailed>(&cmd)) {
      protocol::send_waiting(out, protocol::Frames{"!error", failed->what});
      return;
    } else {
      try {
        do_render(out, std::get<protocol::TaskAssign>(cmd));
      } catch (const std::exception& e) {
        protocol::send_waiting(out, protocol::Frames{"!error", e.what()});
        return;
      }
    }
  }
}

void RenderEngine::load_loop() {
  while (true) {
    protocol::JobSpec job;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait(lock, [&] { return stop_ || !loads_.empty(); });
      if (stop_) return;
      job = std::move(loads_.front());
      loads_.pop_front();
    }
    Command outcome;
    try {
      outcome = LoadDone{job.job, do_load(job)};
    } catch (const std::exception& e) {
      outcome = LoadFailed{e.what()};
    }
    {
      std::lock_guard<std::mutex> lock(mutex_);
      queue_.push_front(std::move(outcome));
    }
    wake_.notify_all();
  }
}

std::shared_ptr<const RenderEngine::Loaded> RenderEngine::loaded_for(uint64_t job) {
  std::lock_guard<std::mutex> lock(mutex_);
  for (const auto& l : loaded_)
    if (std::find(l->jobs.begin(), l->jobs.end(), job) != l->jobs.end()) return l;
  return nullptr;
}

// Runs on the load thread; the parse and BVH build happen outside the lock.
double RenderEngine::do_load(const protocol::JobSpec& job) {
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
    l->renderer = std::make_unique<Renderer>(*l->scene, settings);
    init_s = std::chrono::duration<double>(Clock::now() - t0).count();
    lock.lock();
  }
  l->jobs.push_back(job.job);
  if (l->jobs.size() > 8) l->jobs.erase(l->jobs.begin());  // a scene reused by job after job
  loaded_.push_back(std::move(l));
  return init_s;
}

void RenderEngine::do_render(zmq::socket_t& out, const protocol::TaskAssign& task) {
  const auto loaded = loaded_for(task.job);
  if (!loaded) {
    // A task of a job this thread no longer has (newer jobs were loaded in
    // between). Say so: the socket loop re-registers, the broker requeues it.
    protocol::send_waiting(out, protocol::Frames{"!skipped", std::to_string(task.task)});
    return;
  }
  protocol::TaskResult r;
  r.job = task.job;
  r.task = task.task;
  r.attempt = task.attempt;
  r.y0 = task.y0;
  r.y1 = task.y1;
  r.width = loaded->renderer->settings().width;
  const auto t0 = Clock::now();
  loaded->renderer->render_rows(task.y0, task.y1, r.rgb, &r.stats);
  r.render_s = std::chrono::duration<double>(Clock::now() - t0).count();
  if (throttle_ > 1) {
    const auto t1 = Clock::now();
    sleep_interruptible((throttle_ - 1) * r.render_s);
    r.throttle_s = std::chrono::duration<double>(Clock::now() - t1).count();
  }
  protocol::send_waiting(out, protocol::encode(r));
}

void RenderEngine::sleep_interruptible(double seconds) {
  std::unique_lock<std::mutex> lock(mutex_);
  wake_.wait_for(lock, std::chrono::duration<double>(seconds), [&] { return stop_; });
}

}  // namespace rayfarm
