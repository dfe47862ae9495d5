// Render jobs (render_job.h): validation with messages that name the setting,
// banded rendering for progress, and the stats JSON.
#include "tracer/render_job.h"

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <functional>

#include "tracer/error.h"
#include "tracer/image_io.h"
#include "tracer/image_memory.h"
#include "tracer/nff_reader.h"
#include "tracer/elapsed.h"
#include "tracer/output_file.h"
#include "tracer/streamed_image_file.h"
#include "tracer/text_file.h"

namespace rayfarm {
namespace {

// The side the user did not give keeps the scene's aspect ratio.
int scaled_side(int given, int scene_given_side, int scene_other_side) {
  const double other = std::round(static_cast<double>(given) * scene_other_side / scene_given_side);
  return static_cast<int>(std::clamp(other, 1.0, static_cast<double>(kMaxImageSide)));
}

bool parse_whole_int(std::string_view s, int& value) {
  const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), value);
  return !s.empty() && ec == std::errc() && ptr == s.data() + s.size();
}

// After rendering: a warning if any sample was NaN or Inf (stored as 0), the
// image, and the stats if asked.
void finish_job(const RenderJob& job, const RenderReport& report, const RenderCallbacks& callbacks,
                const std::function<void()>& write_image_file) {
  if (report.rays.non_finite > 0 && callbacks.warning) {
    callbacks.warning(std::to_string(report.rays.non_finite) + " of " + std::to_string(report.rays.eye) +
                      " eye samples were NaN or Inf and are stored as 0: a tracer bug, please report the scene");
  }
  write_image_file();
  if (!job.stats_path.empty()) write_json_file(job.stats_path, stats_json(report));
}

}  // namespace

RenderSettings derive_settings(const Scene& scene, const RenderOverrides& o) {
  const Camera& cam = scene.camera;
  RenderSettings s;
  s.width = o.width.value_or(o.height ? scaled_side(*o.height, cam.height, cam.width) : cam.width);
  s.height = o.height.value_or(o.width ? scaled_side(*o.width, cam.width, cam.height) : cam.height);
  s.spp = o.spp;
  s.max_depth = o.max_depth;
  s.threads = o.threads;
  s.max_isa = o.max_isa;
  s.seed = o.seed;
  s.adaptive_contrast = o.adaptive_contrast;
  s.cutoff = o.cutoff;
  s.robust_bvh = o.robust_bvh;
  validate_settings(s);
  return s;
}

RowRange parse_rows(const std::string& text) {
  const size_t colon = text.find(':');
  RowRange rows;
  if (colon == std::string::npos || !parse_whole_int(std::string_view(text).substr(0, colon), rows.y0) ||
      !parse_whole_int(std::string_view(text).substr(colon + 1), rows.y1))
    throw InputError("--rows: expected Y0:Y1 (e.g. 0:64), found \"" + text + "\"");
  return rows;
}

void check_rows(const RowRange& rows, int height) {
  if (rows.y0 < 0 || rows.y0 >= rows.y1 || rows.y1 > height)
    throw InputError("--rows " + std::to_string(rows.y0) + ":" + std::to_string(rows.y1) +
                     ": expected Y0:Y1 with 0 <= Y0 < Y1 <= " + std::to_string(height));
}

void render_band(const Renderer& renderer, const RowRange& rows, std::vector<float>& rgb, RayStats& stats,
                 const ProgressFn& progress) {
  if (!progress) return renderer.render_rows(rows.y0, rows.y1, rgb, &stats);
  // ~32 updates, in bands that cost nothing (Renderer::band_rows), each still
  // wide enough to keep every thread busy.
  const int unit = renderer.band_rows();
  const int wanted = std::max(unit, (rows.count() + 31) / 32);
  const int band = (wanted + unit - 1) / unit * unit;
  const size_t row_floats = static_cast<size_t>(3) * renderer.settings().width;
  rgb.resize(row_floats * rows.count());
  std::vector<float> part;
  progress(0, rows.count());
  for (int y = rows.y0; y < rows.y1; y += band) {
    const int end = std::min(rows.y1, y + band);
    renderer.render_rows(y, end, part, &stats);
    std::copy(part.begin(), part.end(), rgb.begin() + row_floats * (y - rows.y0));
    progress(end - rows.y0, rows.count());
  }
}

nlohmann::json ray_counts_json(const RayStats& rays) {
  return {{"eye", rays.eye},
          {"eye_hit", rays.eye_hit},
          {"shadow", rays.shadow},
          {"reflection", rays.reflection},
          {"refraction", rays.refraction}};
}

nlohmann::json stats_json(const RenderReport& r) {
  const double total_rays = static_cast<double>(r.rays.total());
  // The resolved count (prepare_render_job), or on a farm the sum over its workers.
  const int threads = r.settings.threads > 0 ? r.settings.threads : render_threads(0);
  return {
      {"seconds", {{"parse", r.seconds.parse}, {"build", r.seconds.build}, {"render", r.seconds.render}}},
      {"rays", ray_counts_json(r.rays)},
      {"non_finite_samples", r.rays.non_finite},
      {"mrays_per_s", r.seconds.render > 0 ? total_rays / r.seconds.render / 1e6 : 0.0},
      {"effects", r.effects.names()},
      {"width", r.settings.width},
      {"height", r.settings.height},
      {"spp", r.settings.spp},
      {"depth", r.settings.max_depth},
      {"threads", threads},
      {"rows", {r.rows.y0, r.rows.y1}},
      {"scene", r.scene_path},
      {"primitives", r.primitives},
      {"warnings", r.warnings},
  };
}

PreparedJob prepare_render_job(const RenderJob& job, const RenderCallbacks& callbacks) {
  check_distinct_files({{"the scene", job.scene_path}, {"-o", job.output_path}, {"--stats", job.stats_path}});
  check_image_path(job.output_path);
  check_output_path(job.output_path);
  if (!job.stats_path.empty()) check_output_path(job.stats_path);

  PreparedJob p;
  RenderReport& report = p.report;
  report.scene_path = job.scene_path;
  const auto start = std::chrono::steady_clock::now();
  p.scene_text = read_nff_text(job.scene_path);
  p.scene = parse_nff(p.scene_text, job.scene_path);
  report.seconds.parse = seconds_since(start);
  report.primitives = p.scene.primitive_count();
  report.warnings = p.scene.warnings;
  if (callbacks.warning)
    for (const std::string& w : p.scene.warnings) callbacks.warning(w);

  report.settings = derive_settings(p.scene, job.overrides);
  // More threads than the machine has would not render any faster: said here,
  // once, in rayfarm's words (not TBB's), and the stats count those it ran.
  const int threads = render_threads(report.settings.threads);
  if (report.settings.threads > threads && callbacks.warning)
    callbacks.warning("--threads " + std::to_string(report.settings.threads) + ": this machine runs " +
                      std::to_string(threads) + " threads at once; rendering on " + std::to_string(threads));
  report.settings.threads = threads;  // resolved: the stats count the threads that ran
  report.rows = job.rows.value_or(RowRange{0, report.settings.height});
  check_rows(report.rows, report.settings.height);
  check_image_memory(report.settings.width, report.rows.count(), physical_memory_bytes(), "this machine's memory");
  return p;
}

void finish_render_job(const RenderJob& job, const RenderReport& report, const std::vector<float>& rgb,
                       const RenderCallbacks& callbacks) {
  finish_job(job, report, callbacks,
             [&] { write_image(job.output_path, report.settings.width, report.rows.count(), rgb); });
}

RenderReport run_render_job(const RenderJob& job, const RenderCallbacks& callbacks) {
  PreparedJob p = prepare_render_job(job, callbacks);
  RenderReport& report = p.report;
  const Renderer renderer(p.scene, report.settings);
  report.seconds.build = renderer.build_seconds();
  report.effects = renderer.effects();

  // The image is written as its bands finish (streamed_image_file.h).
  std::vector<float> rgb;  // sized by render_band, inside the render's time as ever
  StreamedImageFile image(job.output_path, report.settings.width, report.rows.count(), rgb);
  const ProgressFn progress = [&](int done, int total) {
    image.rows_done(done);
    if (callbacks.progress) callbacks.progress(done, total);
  };
  const auto start = std::chrono::steady_clock::now();
  render_band(renderer, report.rows, rgb, report.rays, progress);
  report.seconds.render = seconds_since(start);
  finish_job(job, report, callbacks, [&] { image.finish(); });
  return report;
}

}  // namespace rayfarm
