// Render jobs on the embedded local farm; see farm_render_job.h.
#include "broker/farm_render_job.h"

#include <chrono>

#include "tracer/error.h"
#include "tracer/image_io.h"
#include "tracer/text_file.h"
#include "tracer/nff_reader.h"
#include "tracer/whitted.h"

namespace rayfarm {

RenderReport run_render_job_on_local_farm(const RenderJob& job, const LocalFarmOptions& options,
                                          const RenderCallbacks& callbacks, const std::string& record_path) {
  if (job.rows) throw InputError("--rows renders a band in this process; it cannot be combined with --workers");
  RenderReport report;
  report.scene_path = job.scene_path;
  const auto start = std::chrono::steady_clock::now();
  const std::string text = read_text_file(job.scene_path);
  const Scene scene = parse_nff(text, job.scene_path);  // errors surface here, once, not in every worker
  report.seconds.parse = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  report.primitives = scene.primitive_count();
  report.warnings = scene.warnings;
  if (callbacks.warning)
    for (const std::string& w : scene.warnings) callbacks.warning(w);
  report.settings = derive_settings(scene, job.overrides);
  report.rows = RowRange{0, report.settings.height};
  report.effects = derive_effects(scene);

  LocalFarmResult farm = render_local_farm(text, job.scene_path, report.settings, options);
  report.rays = farm.stats;
  report.seconds.render = farm.record["total_s"].get<double>();
  for (const auto& w : farm.record["workers"])
    report.seconds.build = std::max(report.seconds.build, w["init_s"].get<double>());

  write_image(job.output_path, farm.width, farm.height, farm.rgb);
  if (!job.stats_path.empty()) write_json_file(job.stats_path, stats_json(report));
  if (!record_path.empty()) write_json_file(record_path, farm.record);
  return report;
}

}  // namespace rayfarm
