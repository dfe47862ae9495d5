// Renderer: builds the Embree scene once, then renders bands of rows, the
// threads sharing a band's tiles of pixels (a wavefront of eye rays each).
// Each pixel is estimated from its k x k grid of samples
// (sampler.h): traced whole (render_whole_band()), or adaptively
// (adaptive_sampling.h: the pixel corners, then the whole grid where the
// neighbourhood disagrees; render_block()); pixel_estimate.h counts
// non-finite samples and stores the mean. Pixels through which no eye ray
// can meet the scene take a miss's colour untraced (screen_footprint.h).
#include "tracer/renderer.h"

#include <tbb/blocked_range.h>
#include <tbb/combinable.h>
#include <tbb/info.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cassert>
#include <chrono>
#include <optional>
#include <string>

#include "tracer/adaptive_sampling.h"
#include "tracer/camera.h"
#include "tracer/embree_scene.h"
#include "tracer/error.h"
#include "tracer/pixel_estimate.h"
#include "tracer/sampler.h"
#include "tracer/screen_footprint.h"
#include "tracer/whitted.h"

namespace rayfarm {

namespace {

RenderSettings validated(const RenderSettings& s) {
  validate_settings(s);
  check_embree_isa(s.max_isa, "render settings");
  return s;
}

int arena_size(int threads) { return threads > 0 ? render_threads(threads) : tbb::task_arena::automatic; }

// Calls tile(ya, yb, xa, xb) for each tile of [y0, y1) x [x0, x1), `rows` by
// `columns` (smaller at the far edges), the threads sharing them; a thread
// takes neighbouring tiles, row of tiles by row of tiles. Once `abandoned`
// is set, the tiles left are skipped (the caller throws RenderAbandoned).
template <typename Tile>
void for_each_tile(int y0, int y1, int x0, int x1, int rows, int columns, const std::atomic<bool>& abandoned,
                   const Tile& tile) {
  const int across = (x1 - x0 + columns - 1) / columns, down = (y1 - y0 + rows - 1) / rows;
  tbb::parallel_for(tbb::blocked_range<int>(0, across * down), [&](const tbb::blocked_range<int>& tiles) {
    for (int t = tiles.begin(); t < tiles.end(); ++t) {
      if (abandoned.load(std::memory_order_relaxed)) return;
      const int ya = y0 + (t / across) * rows, xa = x0 + (t % across) * columns;
      tile(ya, std::min(ya + rows, y1), xa, std::min(xa + columns, x1));
    }
  });
}

}  // namespace

int render_threads(int threads) {
  const int machine = tbb::info::default_concurrency();  // the hardware threads this process may use
  return threads > 0 ? std::min(threads, machine) : machine;
}

struct Renderer::Impl {
  RenderSettings settings;
  int k;
  bool adaptive;  // corners first, then the whole grid where the neighbourhood disagrees
  bool whole;     // uniform grids small enough to share wavefronts whole
  mutable tbb::task_arena arena;
  std::optional<EmbreeScene> embree;
  CameraModel camera;
  std::optional<WhittedIntegrator> whitted;
  // The pixels whose eye rays may meet the scene (screen_footprint.h); the
  // others' samples are `miss`, what such a ray would bring back, and their
  // grids sum to `miss_sum`, as traced ones would.
  ScreenFootprint footprint;
  Vec3 miss, miss_sum;
  mutable std::atomic<bool> abandoned{false};  // Renderer::abandon(): skip every tile left

  Impl(const Scene& scene, const RenderSettings& s, const Renderer::Options& o)
      : settings(validated(s)),
        k(grid_size(s.spp)),
        adaptive(is_adaptive(k, s.adaptive_contrast)),
        whole(!adaptive && k * k <= kWholeGridCells),
        arena(arena_size(s.threads)),
        camera(scene.camera, s.width, s.height),
        footprint(s.width, s.height) {
    EmbreeOptions options;
    options.robust_bvh = settings.robust_bvh;
    options.max_isa = settings.max_isa;
    // The BVH build runs in the arena too, so `threads` bounds it as well.
    arena.execute([&] { embree.emplace(scene, options); });
    whitted.emplace(scene, *embree, settings);
    if (o.skip_unseen_pixels) find_footprint();
    miss = whitted->eye_miss_color();
    for (int c = 0; c < k * k; ++c) miss_sum += miss;  // in cell order, as grid_mean() and refine_tile() sum
  }

  // The pixels through which an eye ray may meet the scene's box, narrowed
  // to those through which it may meet a primitive; counted in the build's
  // time.
  void find_footprint() {
    const auto start = std::chrono::steady_clock::now();
    Vec3 lo, hi;
    embree->bounds(lo, hi);
    footprint = ScreenFootprint(camera, settings.width, settings.height, lo, hi);
    footprint.narrow_to_hulls(camera, [&](const auto& visit) { embree->for_each_hull(visit); });
    footprint_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  double footprint_seconds = 0;

  // Whether the lattice points neighbourhood_needs_refinement() compares for
  // pixel (x, y), all within a pixel of its square, may differ: not when
  // every pixel that shares one of them (all within two pixels of it) is
  // ruled out, as they are all `miss` then, and equal samples have no
  // contrast.
  bool corners_may_differ(int x, int y) const { return footprint.near(x, y, 2); }

  // Counts `rays` eye rays that were not traced, their colour being `miss`.
  void count_untraced(int rays, RayStats& stats) const {
    stats.eye += rays;
    if (!is_finite(miss)) stats.non_finite += rays;
  }

  // The eye ray through cell `cell` of pixel (x, y)'s k x k grid (sampler.h).
  Vec3 cell_direction(const PixelGrid& grid, int x, int y, int cell) const {
    const PixelSample s = grid.sample(cell);
    return camera.direction(x + s.x, y + s.y);
  }
  PixelGrid pixel_grid(int x, int y) const { return PixelGrid(pixel_key(settings.seed, x, y), k); }
  static_assert(PixelGrid::kMaxK * PixelGrid::kMaxK >= kMaxSpp, "a valid spp's grid fits a PixelGrid");

  // Each pixel's colour is the mean of its k x k eye rays (sampler.h), or, when
  // adaptive, of its corners (adaptive_sampling.h): a function of the scene,
  // the settings and the pixel alone, since a ray's colour does not depend
  // on the rays traced with it (whitted.h). So
  // neighbouring pixels share wavefronts of eye rays. Deeper levels of a wide
  // wavefront fill Embree's 16-ray packets that one pixel's few mirror and
  // refraction rays leave mostly empty: at 16 spp, 256 rays against one
  // pixel's 16 took 0.93x the render time on balls, 0.96x on tetra, 0.97x
  // on mount and gears, 0.98x on rings (one thread, 7 pairs each). 64 rays
  // gained most of that on balls and mount, 256 another 1% there (5 pairs;
  // tetra and gears, noisier, 1.06x and 1.17x faster at 256 than at 64);
  // 1024 made gears 1.2x slower (a level outgrows the cache). Those were
  // pixels of one row. Pixels of a tile, 8 rows by 2 columns, made the 256
  // rays' deeper levels start closer together: rings rendered in 0.970x the
  // time of 16 pixels of a row, balls 0.973x, mount 0.972x and gears 0.940x
  // (whole processes, 9-15 pairs); tiles of 2, 4 and 16 rows 0.992x, 0.974x
  // and 0.975x on rings. With tiles, 512 rays (8 rows by 4 columns) took
  // 0.993x the time of 256 on rings and 0.988x on gears, 1024 0.995x and
  // 1.010x that of 512; 16 rows by 2 columns 0.997x and 0.995x. (The
  // adaptive renders' rows of corners and refined grids: 512 rays
  // 0.99-1.01x the time of 256.)
  static constexpr int kWavefront = 512;
  static constexpr int kTileRows = 8;
  static constexpr int kWholeGridCells = 64;  // uniform grids traced whole: 8 or more pixels per wavefront
  static_assert(kWholeGridCells * kTileRows <= kWavefront, "a tile of the widest whole grids fills a wavefront");

  // Uniform pixels of rows [y0, y1), whole grids of at most kWholeGridCells
  // cells, into `out` (rows `row_floats` apart, from pixel (x0, y0)): each
  // wavefront the pixels of one tile, as many columns of the rows as fit.
  // At most kWavefront / (k * k) rows.
  void render_whole_strip(int y0, int y1, int x0, int x1, float* out, size_t row_floats, RayStats& stats) const {
    const int cells = k * k;
    assert((y1 - y0) * cells <= kWavefront);
    const int columns = tile_columns(y1 - y0);
    Vec3Scratch<kWavefront> dirs, rgb;
    for (int xa = x0; xa < x1; xa += columns) {
      const int xb = std::min(xa + columns, x1);
      int traced = 0, unseen = 0;
      for (int y = y0; y < y1; ++y) {
        for (int x = xa; x < xb; ++x) {
          if (!footprint.pixel(x, y)) continue;
          const PixelGrid grid = pixel_grid(x, y);
          for (int c = 0; c < cells; ++c) dirs[traced++] = cell_direction(grid, x, y, c);
        }
      }
      if (traced > 0) whitted->trace_eye_rays(dirs.data(), traced, rgb.data(), stats);
      count_non_finite(rgb.data(), traced, stats);
      const Vec3* grid = rgb.data();
      for (int y = y0; y < y1; ++y) {
        for (int x = xa; x < xb; ++x) {
          float* pixel = out + row_floats * (y - y0) + 3 * (x - x0);
          if (!footprint.pixel(x, y)) {
            store_mean(miss_sum / cells, pixel);
            unseen += cells;
            continue;
          }
          store_mean(grid_mean(grid, cells), pixel);
          grid += cells;
        }
      }
      count_untraced(unseen, stats);
    }
  }

  // Rows and columns of a tile of whole grids: kTileRows rows where a
  // wavefront holds them, and as many columns as fill it.
  int tile_rows() const { return std::min(kTileRows, kWavefront / (k * k)); }
  int tile_columns(int rows) const { return std::max(1, kWavefront / (k * k) / rows); }

  // Uniform pixels [x0, x1) of rows [y0, y1), whole grids, into out (rows
  // `row_floats` apart, from pixel (x0, y0)): the band cut into tiles, which
  // the threads share; a band lower than a tile (a farm's task of a few rows,
  // or a span of one row) into tiles as wide as fill a wavefront. Call inside
  // the arena.
  void render_whole_band(int y0, int y1, int x0, int x1, float* out, size_t row_floats,
                         tbb::combinable<RayStats>& per_thread) const {
    if (y1 <= y0 || x1 <= x0) return;
    const int rows = std::min(tile_rows(), y1 - y0);
    for_each_tile(y0, y1, x0, x1, rows, tile_columns(rows), abandoned, [&](int ya, int yb, int xa, int xb) {
      render_whole_strip(ya, yb, xa, xb, out + row_floats * (ya - y0) + 3 * (xa - x0), row_floats,
                         per_thread.local());
    });
  }

  // The corner samples of a window of the pixel lattice, row-major: lattice
  // points (i, j) for i in [i0, i0 + width), j in [j0, j0 + height).
  struct CornerWindow {
    int i0 = 0, j0 = 0, width = 0, height = 0;
    std::vector<Vec3> rgb;
    Vec3* at(int i, int j) { return rgb.data() + size_t(j - j0) * width + (i - i0); }
    const Vec3& operator()(int i, int j) const { return rgb[size_t(j - j0) * width + (i - i0)]; }
  };

  // Traces lattice points [ia, ib) x [ja, jb) of `w` into it, one wavefront
  // (at most kWavefront points): the eye rays through those pixel corners.
  // Counts them in `stats`, and their non-finite colours when `own`.
  void trace_corner_tile(CornerWindow& w, int ja, int jb, int ia, int ib, bool own, RayStats& stats) const {
    const int width = ib - ia, count = width * (jb - ja);
    assert(count <= kWavefront);
    Vec3Scratch<kWavefront> dirs, rgb, traced_rgb;
    int traced_at[kWavefront], traced = 0;
    for (int n = 0; n < count; ++n) {
      const int i = ia + n % width, j = ja + n / width;
      rgb[n] = miss;
      if (!footprint.corner(i, j)) continue;
      dirs[traced] = camera.direction(i, j);
      traced_at[traced++] = n;
    }
    if (traced > 0) whitted->trace_eye_rays(dirs.data(), traced, traced_rgb.data(), stats);
    for (int t = 0; t < traced; ++t) rgb[traced_at[t]] = traced_rgb[t];
    stats.eye += count - traced;  // their non-finite colours are counted below, with the rest
    for (int j = ja; j < jb; ++j) {
      const Vec3* row = rgb.data() + size_t(j - ja) * width;
      std::copy(row, row + width, w.at(ia, j));
      if (own) count_non_finite(row, width, stats);
    }
  }

  // Lattice points [ia, ib) x [ja, jb) of `w`, in tiles of kTileRows rows
  // (fewer where the region is narrow) that fill a wavefront, which the
  // threads share. Counted in `per_thread` when `own`.
  void trace_corner_region(CornerWindow& w, int ja, int jb, int ia, int ib, bool own,
                           tbb::combinable<RayStats>& per_thread) const {
    if (ja >= jb || ia >= ib) return;
    const int columns = std::min(ib - ia, kWavefront / kTileRows);
    const int rows = std::min(jb - ja, kWavefront / columns);
    for_each_tile(ja, jb, ia, ib, rows, columns, abandoned, [&](int ja_t, int jb_t, int ia_t, int ib_t) {
      RayStats neighbours;
      trace_corner_tile(w, ja_t, jb_t, ia_t, ib_t, own, own ? per_thread.local() : neighbours);
    });
  }

  // The window's lattice points around block [y0, y1) x [x0, x1). A lattice
  // point belongs to the pixel whose top left corner it is (the last row and
  // column to the pixels of the image's bottom and right edges): the block's
  // own points count in `per_thread`; its neighbours', traced again by the
  // block beside them, do not, so a band's statistics are its own pixels'
  // whatever the bands are. The window is cut into its own points and the
  // neighbours' rows and columns around them, each traced in tiles.
  void trace_window(CornerWindow& w, int y0, int y1, int x0, int x1, tbb::combinable<RayStats>& per_thread) const {
    const int own_bottom = y1 == settings.height ? y1 + 1 : y1;
    const int own_right = x1 == settings.width ? x1 + 1 : x1;
    const int rows[] = {w.j0, y0, own_bottom, w.j0 + w.height};
    const int columns[] = {w.i0, x0, own_right, w.i0 + w.width};
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) {
        trace_corner_region(w, rows[r], rows[r + 1], columns[c], columns[c + 1], r == 1 && c == 1, per_thread);
      }
    }
  }

  // Pixels [xa, xb) of rows [ya, yb) (at most kTileRows by kTileColumns),
  // into out (rows `row_floats` apart): adaptive pixels from their corners in
  // `corners`, the whole grid where their neighbourhood disagrees; without
  // corners (a uniform grid too large to trace whole) every pixel's whole
  // grid. Refined pixels share wavefronts, taken in tiles as render_whole_band()
  // takes them (columns of kTileRows rows, each as wide as fill a wavefront
  // when all are refined), and each sums its grid in cell order, so its mean
  // has the bits of a uniform render.
  static constexpr int kTileColumns = 64;
  void refine_tile(int ya, int yb, int xa, int xb, const CornerWindow* corners, float* out, size_t row_floats,
                   RayStats& stats) const {
    assert(yb - ya <= kTileRows && xb - xa <= kTileColumns);
    Vec3 sums[kTileRows][kTileColumns];
    bool refined[kTileRows][kTileColumns];
    for (int y = ya; y < yb; ++y) {
      for (int x = xa; x < xb; ++x) {
        refined[y - ya][x - xa] = !corners || (corners_may_differ(x, y) &&
                                               neighbourhood_needs_refinement(x, y, settings.width, settings.height,
                                                                              settings.adaptive_contrast, *corners));
      }
    }
    Vec3Scratch<kWavefront> dirs, rgb;
    Vec3* slot_sum[kWavefront];
    int traced = 0;
    const auto flush = [&] {
      whitted->trace_eye_rays(dirs.data(), traced, rgb.data(), stats);
      count_non_finite(rgb.data(), traced, stats);
      for (int i = 0; i < traced; ++i) *slot_sum[i] += rgb[i];
      traced = 0;
    };
    const int cells = k * k;
    const int columns = tile_columns(kTileRows);
    for (int xc = xa; xc < xb; xc += columns) {
      for (int y = ya; y < yb; ++y) {
        for (int x = xc; x < std::min(xc + columns, xb); ++x) {
          if (!refined[y - ya][x - xa]) continue;
          Vec3& sum = sums[y - ya][x - xa] = Vec3{};
          if (!footprint.pixel(x, y)) {
            sum = miss_sum;
            count_untraced(cells, stats);
            continue;
          }
          const PixelGrid grid = pixel_grid(x, y);
          for (int c = 0; c < cells; ++c) {
            dirs[traced] = cell_direction(grid, x, y, c);
            slot_sum[traced++] = &sum;
            if (traced == kWavefront) flush();
          }
        }
      }
    }
    if (traced > 0) flush();
    for (int y = ya; y < yb; ++y) {
      for (int x = xa; x < xb; ++x) {
        const Vec3 mean = refined[y - ya][x - xa] ? sums[y - ya][x - xa] / cells : corner_mean(x, y, *corners);
        store_mean(mean, out + row_floats * (y - ya) + 3 * (x - xa));
      }
    }
  }

  // Block [y0, y1) x [x0, x1) into out (rows `row_floats` apart), unless the
  // grids are traced whole: when adaptive, the corners of the block and of
  // the pixels around it into `corners` (reused from block to block), then
  // each pixel. Call inside the arena.
  void render_block(int y0, int y1, int x0, int x1, float* out, size_t row_floats, CornerWindow& corners,
                    tbb::combinable<RayStats>& per_thread) const {
    if (adaptive) {
      corners.i0 = std::max(0, x0 - 1);
      corners.j0 = std::max(0, y0 - 1);
      corners.width = std::min(settings.width, x1 + 1) + 1 - corners.i0;
      corners.height = std::min(settings.height, y1 + 1) + 1 - corners.j0;
      corners.rgb.resize(size_t(corners.width) * corners.height);
      trace_window(corners, y0, y1, x0, x1, per_thread);
    }
    const CornerWindow* corner_samples = adaptive ? &corners : nullptr;
    for_each_tile(y0, y1, x0, x1, kTileRows, kTileColumns, abandoned, [&](int ya, int yb, int xa, int xb) {
      refine_tile(ya, yb, xa, xb, corner_samples, out + row_floats * (ya - y0) + 3 * (xa - x0), row_floats,
                  per_thread.local());
    });
  }

  // Rows of adaptive blocks: the corners of at most this many rows (and of
  // the rows above and below) are held at a time.
  static constexpr int kBlockRows = 64;
};

Renderer::Renderer(const Scene& scene, const RenderSettings& settings) : Renderer(scene, settings, Options{}) {}

Renderer::Renderer(const Scene& scene, const RenderSettings& settings, const Options& options)
    : impl_(std::make_unique<Impl>(scene, settings, options)) {}

Renderer::~Renderer() = default;

void Renderer::render_rows(int y0, int y1, std::vector<float>& rgb, RayStats* stats) const {
  const Impl& im = *impl_;
  if (y0 < 0 || y1 < y0 || y1 > im.settings.height) {
    throw InputError("render: rows [" + std::to_string(y0) + ", " + std::to_string(y1) +
                     ") outside the image (height " + std::to_string(im.settings.height) + ")");
  }
  const int width = im.settings.width;
  const size_t row_floats = size_t(3) * width;
  rgb.assign(row_floats * (y1 - y0), 0.0f);
  tbb::combinable<RayStats> per_thread;
  im.arena.execute([&] {
    if (im.whole) {
      im.render_whole_band(y0, y1, 0, width, rgb.data(), row_floats, per_thread);
      return;
    }
    // One corner buffer for the band, reused by its blocks: with a new one per
    // block, perf put 10% of tetra's adaptive render in the kernel clearing
    // fresh pages (paired whole-process runs could not tell the two apart).
    Impl::CornerWindow corners;
    for (int b0 = y0; b0 < y1; b0 += Impl::kBlockRows) {
      const int b1 = std::min(b0 + Impl::kBlockRows, y1);
      im.render_block(b0, b1, 0, width, rgb.data() + row_floats * (b0 - y0), row_floats, corners, per_thread);
    }
  });
  if (im.abandoned) throw RenderAbandoned();
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
  im.arena.execute([&] {
    if (im.whole) {
      im.render_whole_band(y, y + 1, x0, x1, rgb.data(), rgb.size(), per_thread);
      return;
    }
    Impl::CornerWindow corners;
    im.render_block(y, y + 1, x0, x1, rgb.data(), rgb.size(), corners, per_thread);
  });
  if (im.abandoned) throw RenderAbandoned();
  if (stats) per_thread.combine_each([&](const RayStats& s) { *stats += s; });
}

void Renderer::abandon() const { impl_->abandoned = true; }
void Renderer::resume() const { impl_->abandoned = false; }

const RenderSettings& Renderer::settings() const { return impl_->settings; }
EffectSet Renderer::effects() const { return impl_->whitted->effects(); }
int Renderer::band_rows() const { return impl_->adaptive ? Impl::kBlockRows : Impl::kTileRows; }

double Renderer::build_seconds() const { return impl_->embree->build_seconds() + impl_->footprint_seconds; }

}  // namespace rayfarm
