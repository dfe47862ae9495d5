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

RenderEngine::RenderEngine(zmq::context_t& context, std::string endpoint, int threads, double throttle)
    : context_(context), endpoint_(std::move(endpoint)), threads_(threads), throttle_(throttle),
      thread_([this] { loop(); }) {}

RenderEngine::~RenderEngine() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
    queue_.clear();
  }
  wake_.notify_all();
  thread_.join();
}

void RenderEngine::load(const protocol::JobSpec& job) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    queue_.emplace_back(job);
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
  // Tasks only: a queued job load stays, the socket loop counts on its answer.
  std::lock_guard<std::mutex> lock(mutex_);
  queue_.erase(std::remove_if(queue_.begin(), queue_.end(),
                              [](const Command& c) { return std::holds_alternative<protocol::TaskAssign>(c); }),
               queue_.end());
}

void RenderEngine::loop() {
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
    try {
      if (auto* job = std::get_if<protocol::JobSpec>(&cmd))
        do_load(out, *job);
      else
        do_render(out, std::get<protocol::TaskAssign>(cmd));
    } catch (const std::exception& e) {
      protocol::send_waiting(out, protocol::Frames{"!error", e.what()});
      return;
    }
  }
}

void RenderEngine::do_load(zmq::socket_t& out, const protocol::JobSpec& job) {
  const std::string key = cache_key(job);
  double init_s = 0;
  if (key != cache_key_) {
    const auto t0 = Clock::now();
    renderer_.reset();
    scene_ = std::make_unique<Scene>(parse_nff(job.scene_text, job.scene_name));
    RenderSettings settings = job.settings;
    settings.threads = threads_;
    renderer_ = std::make_unique<Renderer>(*scene_, settings);
    cache_key_ = key;
    init_s = std::chrono::duration<double>(Clock::now() - t0).count();
  }
  loaded_job_ = job.job;
  protocol::send_waiting(out, protocol::encode(protocol::JobReady{job.job, init_s}));
}

void RenderEngine::do_render(zmq::socket_t& out, const protocol::TaskAssign& task) {
  if (task.job != loaded_job_ || !renderer_) {
    // A task of a job this thread no longer has (a newer job was loaded in
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
  r.width = renderer_->settings().width;
  const auto t0 = Clock::now();
  renderer_->render_rows(task.y0, task.y1, r.rgb, &r.stats);
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
