// Renderer: the one entry point the rest of rayfarm renders through.
// Construct it from a parsed Scene and RenderSettings (this builds the Embree
// BVH once), then ask for any band of scanlines, in any order, from any thread:
// the band's float RGB is byte-identical to the same rows of a full render.
#pragma once

#include <atomic>
#include <memory>
#include <stdexcept>
#include <vector>

#include "tracer/ray_stats.h"
#include "tracer/render_settings.h"
#include "tracer/scene.h"

namespace rayfarm {

// The threads a render asking for `threads` (0 = all) runs on: this
// machine's hardware threads at most. TBB gives an arena no more workers
// than that whatever it asks for, and said so in a warning of its own.
int render_threads(int threads);

// A render stopped by Renderer::abandon(): its pixels are incomplete.
struct RenderAbandoned : std::runtime_error {
  RenderAbandoned() : std::runtime_error("render abandoned") {}
};

class Renderer {
 public:
  // How pixels are computed, never what they are: for the tests and
  // measurements that hold one way to the other.
  struct Options {
    // Pixels through which no eye ray can meet the scene's bounding box
    // take the background without tracing (screen_footprint.h).
    bool skip_unseen_pixels = true;
  };

  Renderer(const Scene& scene, const RenderSettings& settings);
  Renderer(const Scene& scene, const RenderSettings& settings, const Options& options);
  ~Renderer();
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;

  // Renders rows [y0, y1) into `rgb`, resized to (y1 - y0) * width * 3 floats,
  // row-major, top row first. Adds the rays it traced to `stats` when given.
  void render_rows(int y0, int y1, std::vector<float>& rgb, RayStats* stats = nullptr) const;
  // Renders pixels [x0, x1) of row y into `rgb`, resized to (x1 - x0) * 3
  // floats: the same bytes as those pixels of render_rows(y, y + 1). A farm
  // cuts the last rows of a job into such spans.
  void render_span(int y, int x0, int x1, std::vector<float>& rgb, RayStats* stats = nullptr) const;

  // Stops every render of this renderer, running or to come, at its next
  // tile, from any thread: they throw RenderAbandoned, until resume(). A
  // worker that is told to stop, or whose broker has requeued the task it
  // renders, does not first finish a task of minutes.
  void abandon() const;
  // Renders after this run to the end again (none may be running).
  void resume() const;

  // A run of bands, each a multiple of this many rows but the last, renders
  // in the time of one call over all their rows: the adaptive sampler's
  // blocks share their edge rows' corner samples, which a band boundary
  // inside a block would trace twice.
  int band_rows() const;

  const RenderSettings& settings() const;
  EffectSet effects() const;
  double build_seconds() const;  // the constructor's BVH build and screen footprint, in seconds

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace rayfarm
