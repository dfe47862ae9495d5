// Renderer: builds the Embree scene once, then renders bands of rows in
// parallel. Each pixel is estimated by render_pixels() -- the one place
// that decides where a pixel's samples go -- from its jittered k x k grid
// (sampler.h), optionally adaptive (adaptive_sampling.h); pixel_estimate.h
// counts non-finite samples and stores the mean.
#include "tracer/renderer.h"

#include <tbb/blocked_range.h>
#include <tbb/combinable.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <optional>
#include <string>

#include "tracer/camera.h"
#include "tracer/embree_scene.h"
#include "tracer/error.h"
#include "tracer/pixel_estimate.h"
#include "tracer/sampler.h"
#include "tracer/whitted.h"

namespace rayfarm {

namespace {

RenderSettings validated(const RenderSettings& s) {
  validate_settings(s);
  check_embree_isa(s.max_isa, "render settings");
  return s;
}

int arena_size(int threads) { return threads > 0 ? threads : tbb::task_arena::automatic; }

}  // namespace

struct Renderer::Impl {
  RenderSettings settings;
  int k;
  mutable tbb::task_arena arena;
  std::optional<EmbreeScene> embree;
  CameraModel camera;
  std::optional<WhittedIntegrator> whitted;

  Impl(const Scene& scene, const RenderSettings& s)
      : settings(validated(s)),
        k(grid_size(s.spp)),
        arena(arena_size(s.threads)),
        camera(scene.camera, s.width, s.height) {
    EmbreeOptions options;
    options.robust_bvh = settings.robust_bvh;
    options.max_isa = settings.max_isa;
    // The BVH build runs in the arena too, so `threads` bounds it as well.
    arena.execute([&] { embree.emplace(scene, options); });
    whitted.emplace(scene, *embree, settings);
  }

  // Traces eye rays through cells of pixel (x, y) of its jittered k x k grid
  // (sampler.h): `shade` for finish_pixel() (adaptive_sampling.h).
  auto pixel_shader(int x, int y, RayStats& stats) const {
    return [this, x, y, &stats, key = pixel_key(settings.seed, x, y)](const int* cells, int count, Vec3* rgb) {
      Vec3Scratch<kSampleBatch> dirs;
      for (int i = 0; i < count; ++i) dirs[i] = cell_direction(key, x, y, cells[i]);
      whitted->trace_eye_rays(dirs.data(), count, rgb, stats);
    };
  }
  Vec3 cell_direction(uint64_t key, int x, int y, int cell) const {
    const PixelSample s = jittered_sample(key, cell, k);
    return camera.direction(x + s.x, y + s.y);
  }

  // Pixels [x0, x1) of row y into out[0 .. 3 (x1 - x0)). Each pixel's colour
  // is the mean of its k x k jittered eye rays, or of the adaptive subset
  // (adaptive_sampling.h), and depends on nothing else: a ray's colour does
  // not depend on the rays traced with it (whitted.h). So neighbouring pixels
  // share one wavefront of eye rays: whole pixels for a uniform grid of at
  // most kWholeGridCells, otherwise their first cells (an adaptive pixel's
  // four corners, or none); then the adaptive pixels that need their whole
  // grid share wavefronts again (refine_pixels()), while a larger grid's
  // pixels finish one by one. Deeper levels
  // of a wide wavefront fill Embree's 16-ray packets that one pixel's few
  // mirror and refraction rays leave mostly empty: at 16 spp, 256 rays
  // against one pixel's 16 took 0.93x the render time on balls, 0.96x on
  // tetra, 0.97x on mount and gears, 0.98x on rings (one thread, 7 pairs
  // each). 64 rays gained most of that on balls and mount, 256 another 1%
  // there (5 pairs; tetra and gears, noisier, 1.06x and 1.17x faster at 256
  // than at 64); 1024 made gears 1.2x slower (a level outgrows the cache).
  static constexpr int kWavefront = 256;
  static constexpr int kWholeGridCells = kWavefront / 4;  // 4 pixels or more per wavefront
  void render_pixels(int y, int x0, int x1, float* out, RayStats& stats) const {
    const double threshold = settings.adaptive_contrast;
    const bool whole = threshold <= 0 && k * k <= kWholeGridCells;
    const CoarseCells first = first_cells(k, threshold);
    const int per_pixel = whole ? k * k : first.count;
    // Adaptive, with cells left after the first ones (k >= 3), few enough
    // to share wavefronts (refine_pixels()).
    const bool shared_refinement = first.count > 0 && first.count < k * k && k * k <= kWholeGridCells;
    const int group = per_pixel > 0 ? kWavefront / per_pixel : 1;
    Vec3Scratch<kWavefront> dirs, rgb;
    for (int xa = x0; xa < x1; xa += group) {
      const int xb = std::min(xa + group, x1);
      int traced = 0;
      for (int x = xa; x < xb; ++x) {
        const uint64_t key = pixel_key(settings.seed, x, y);
        for (int i = 0; i < per_pixel; ++i) dirs[traced++] = cell_direction(key, x, y, whole ? i : first.index[i]);
      }
      if (traced > 0) {
        whitted->trace_eye_rays(dirs.data(), traced, rgb.data(), stats);
        count_non_finite(rgb.data(), traced, stats);
      }
      if (whole) {
        for (int x = xa; x < xb; ++x) {
          store_mean(grid_mean(rgb.data() + per_pixel * (x - xa), per_pixel), out + 3 * (x - x0));
        }
      } else if (shared_refinement) {
        refine_pixels(y, xa, xb, first, rgb.data(), out + 3 * (xa - x0), stats);
      } else {
        for (int x = xa; x < xb; ++x) {
          finish_estimate(k, threshold, first, rgb.data() + per_pixel * (x - xa), pixel_shader(x, y, stats), stats,
                          out + 3 * (x - x0));
        }
      }
    }
  }

  // Adaptive pixels [xa, xb) of row y, their first cells' values traced
  // (first_rgb, first.count per pixel), into out[0 .. 3 (xb - xa)). The
  // pixels whose first cells disagree take their other cells in shared
  // wavefronts too: traced pixel by pixel, a pixel's 12 further rays (16
  // spp) left its mirror and shadow packets mostly empty. Means as
  // finish_pixel() takes them, bit for bit.
  void refine_pixels(int y, int xa, int xb, const CoarseCells& first, const Vec3* first_rgb, float* out,
                     RayStats& stats) const {
    int rest_cells[kWholeGridCells];  // the cells a refined pixel adds, the same for every pixel
    const int rest = other_cells(0, k * k, first, 0, rest_cells);
    Vec3Scratch<kWavefront> dirs, rgb;
    int refined[kWavefront];
    for (int x = xa; x < xb;) {
      int pixels = 0, traced = 0;
      for (; x < xb && traced + rest <= kWavefront; ++x) {
        const Vec3* mine = first_rgb + first.count * (x - xa);
        if (!needs_refinement(mine, first.count, settings.adaptive_contrast)) {
          store_mean(grid_mean(mine, first.count), out + 3 * (x - xa));
          continue;
        }
        refined[pixels++] = x;
        const uint64_t key = pixel_key(settings.seed, x, y);
        for (int i = 0; i < rest; ++i) dirs[traced++] = cell_direction(key, x, y, rest_cells[i]);
      }
      if (traced == 0) continue;
      whitted->trace_eye_rays(dirs.data(), traced, rgb.data(), stats);
      count_non_finite(rgb.data(), traced, stats);
      for (int i = 0; i < pixels; ++i) {
        const int x_i = refined[i];
        store_mean(refined_mean(k, first, first_rgb + first.count * (x_i - xa), rgb.data() + rest * i),
                   out + 3 * (x_i - xa));
      }
    }
  }
};

Renderer::Renderer(const Scene& scene, const RenderSettings& settings)
    : impl_(std::make_unique<Impl>(scene, settings)) {}

Renderer::~Renderer() = default;

void Renderer::render_rows(int y0, int y1, std::vector<float>& rgb, RayStats* stats) const {
  const Impl& im = *impl_;
  if (y0 < 0 || y1 < y0 || y1 > im.settings.height) {
    throw InputError("render: rows [" + std::to_string(y0) + ", " + std::to_string(y1) +
                     ") outside the image (height " + std::to_string(im.settings.height) + ")");
  }
  const size_t row_floats = size_t(3) * im.settings.width;
  rgb.assign(row_floats * (y1 - y0), 0.0f);
  tbb::combinable<RayStats> per_thread;
  im.arena.execute([&] {
    tbb::parallel_for(tbb::blocked_range<int>(y0, y1, 1), [&](const tbb::blocked_range<int>& rows) {
      RayStats local;
      for (int y = rows.begin(); y < rows.end(); ++y)
        im.render_pixels(y, 0, im.settings.width, rgb.data() + row_floats * (y - y0), local);
      per_thread.local() += local;
    });
  });
  if (stats) per_thread.combine_each([&](const RayStats& s) { *stats += s; });
}

// One row's pixels, split among the threads in blocks of pixels (a span is
// one row, so rows cannot be the unit here).
void Renderer::render_span(int y, int x0, int x1, std::vector<float>& rgb, RayStats* stats) const {
  const Impl& im = *impl_;
  if (y < 0 || y >= im.settings.height || x0 < 0 || x1 < x0 || x1 > im.settings.width) {
    throw InputError("render: pixels [" + std::to_string(x0) + ", " + std::to_string(x1) + ") of row " +
                     std::to_string(y) + " outside the image (" + std::to_string(im.settings.width) + "x" +
                     std::to_string(im.settings.height) + ")");
  }
  rgb.assign(size_t(3) * (x1 - x0), 0.0f);
  tbb::combinable<RayStats> per_thread;
  constexpr int kPixelsPerBlock = 8;
  im.arena.execute([&] {
    tbb::parallel_for(tbb::blocked_range<int>(x0, x1, kPixelsPerBlock), [&](const tbb::blocked_range<int>& px) {
      RayStats local;
      im.render_pixels(y, px.begin(), px.end(), rgb.data() + 3 * (px.begin() - x0), local);
      per_thread.local() += local;
    });
  });
  if (stats) per_thread.combine_each([&](const RayStats& s) { *stats += s; });
}

const RenderSettings& Renderer::settings() const { return impl_->settings; }
EffectSet Renderer::effects() const { return impl_->whitted->effects(); }
double Renderer::build_seconds() const { return impl_->embree->build_seconds(); }

}  // namespace rayfarm
