// Render jobs on the embedded local farm; see farm_render_job.h.
#include "broker/farm_render_job.h"

#include <algorithm>

#include "tracer/error.h"
#include "tracer/text_file.h"
#include "tracer/whitted.h"

namespace rayfarm {

RenderReport run_render_job_on_local_farm(const RenderJob& job, const LocalFarmOptions& options,
                                          const RenderCallbacks& callbacks, const std::string& record_path) {
  if (job.rows) throw InputError("--rows renders a band in this process; it cannot be combined with --workers");
  // Parsed here too, so scene errors surface once, not in every worker.
  PreparedJob p = prepare_render_job(job, callbacks);
  RenderReport& report = p.report;
  report.effects = derive_effects(p.scene);

  LocalFarmResult farm = render_local_farm(p.scene_text, job.scene_path, report.settings, options);
  report.rays = farm.stats;
  report.seconds.render = farm.record["total_s"].get<double>();
  for (const auto& w : farm.record["workers"])
    report.seconds.build = std::max(report.seconds.build, w["init_s"].get<double>());

  finish_render_job(job, report, farm.rgb, callbacks);
  if (!record_path.empty()) write_json_file(record_path, farm.record);
  return report;
}

}  // namespace rayfarm
