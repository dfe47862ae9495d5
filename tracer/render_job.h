// Render jobs: the path from "a scene file and some options" to "an image and a
// stats file", in pieces that `rayfarm render` and the farm both use -- settings
// derived from the scene plus overrides, row bands, progress-reporting band
// rendering, and the stats JSON (key names are part of rayfarm's interface:
// scripts and the study plots read them).
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "tracer/ray_stats.h"
#include "tracer/render_settings.h"
#include "tracer/renderer.h"
#include "tracer/scene.h"

namespace rayfarm {

// What the user may change; everything unset comes from the scene.
struct RenderOverrides {
  std::optional<int> width;   // only one of width/height given: the other keeps
  std::optional<int> height;  // the scene's aspect ratio
  int spp = 16;               // must be k*k
  int max_depth = 5;
  int threads = 0;  // 0 = all hardware threads
  std::string max_isa;  // caps Embree's kernel width (speed only, never bytes)
  uint64_t seed = 0;
  double adaptive_contrast = 0;
  double cutoff = 0;  // in [0, 1]
  bool robust_bvh = false;
};

// Scene resolution + overrides, validated: InputError "spp must be ...".
RenderSettings derive_settings(const Scene& scene, const RenderOverrides& overrides);

// A band of scanlines [y0, y1), top row 0.
struct RowRange {
  int y0 = 0;
  int y1 = 0;
  int count() const { return y1 - y0; }
};

// Parses "Y0:Y1" (InputError "--rows: expected Y0:Y1 ..."); check_rows then
// requires 0 <= Y0 < Y1 <= height.
RowRange parse_rows(const std::string& text);
void check_rows(const RowRange& rows, int height);

// Called after each band with rows finished so far and rows in total.
using ProgressFn = std::function<void(int done, int total)>;

// Renders `rows` into `rgb` ((y1 - y0) * width * 3 floats), adding rays to
// `stats`. With a progress callback the rows go in bands of a few percent,
// which renders the same bytes (Renderer guarantees band independence).
void render_band(const Renderer& renderer, const RowRange& rows, std::vector<float>& rgb, RayStats& stats,
                 const ProgressFn& progress = {});

// Wall-clock seconds of the three phases.
struct PhaseSeconds {
  double parse = 0;
  double build = 0;
  double render = 0;
};

// Everything the stats JSON reports about one render.
struct RenderReport {
  std::string scene_path;
  size_t primitives = 0;
  std::vector<std::string> warnings;
  RenderSettings settings;
  RowRange rows;
  EffectSet effects;
  RayStats rays;
  PhaseSeconds seconds;
};

// {"seconds": {"parse", "build", "render"}, "rays": {"eye", "eye_hit", "shadow",
//  "reflection", "refraction"}, "non_finite_samples", "mrays_per_s", "effects": [...], "width",
//  "height", "spp", "depth", "threads", "rows": [y0, y1], "scene", "primitives",
//  "warnings": [...]}. "threads" is the resolved count, never 0; on a farm,
//  the sum of the threads of the workers that rendered tasks.
// {"eye", "eye_hit", "shadow", "reflection", "refraction"}: the ray counts as
// every stats and cache file writes them.
nlohmann::json ray_counts_json(const RayStats& rays);
nlohmann::json stats_json(const RenderReport& report);

// One complete `rayfarm render`: output and stats paths are checked before the
// (possibly long) render starts.
struct RenderJob {
  std::string scene_path;
  std::string output_path;
  std::string stats_path;         // empty: no stats file
  std::optional<RowRange> rows;   // unset: the whole image
  RenderOverrides overrides;
};

struct RenderCallbacks {
  // Each scene warning, before rendering; after it, non-finite samples if any.
  std::function<void(const std::string&)> warning;
  ProgressFn progress;                              // unset: render in one call
};

RenderReport run_render_job(const RenderJob& job, const RenderCallbacks& callbacks = {});

// The steps every render job, in-process or on a farm, takes before rendering:
// outputs checked (a long render must not fail at the end), the scene read,
// parsed and its warnings reported, settings and rows derived. The NFF text is
// kept for a farm to send on.
struct PreparedJob {
  std::string scene_text;
  Scene scene;
  RenderReport report;  // scene, settings, rows and parse time filled in
};
PreparedJob prepare_render_job(const RenderJob& job, const RenderCallbacks& callbacks = {});

// The step after rendering: a warning if any sample was NaN or Inf (stored as
// 0), the image of `report.rows`, and the stats if asked.
void finish_render_job(const RenderJob& job, const RenderReport& report, const std::vector<float>& rgb,
                       const RenderCallbacks& callbacks = {});

}  // namespace rayfarm
