// `rayfarm render --workers N`: the same RenderJob (tracer/render_job.h) as an
// in-process render -- same settings derivation, image and stats JSON -- but the
// rows are rendered by N local worker processes through the embedded farm
// (broker/local_farm.h). The image is byte-identical to the in-process one.
#pragma once

#include <string>

#include "broker/local_farm.h"
#include "tracer/render_job.h"

namespace rayfarm {

// Stats JSON seconds: parse = the broker's parse, build = the slowest worker's
// BVH build, render = announce to assembled image. `record_path` (optional)
// receives the farm's job record.
RenderReport run_render_job_on_local_farm(const RenderJob& job, const LocalFarmOptions& options,
                                          const RenderCallbacks& callbacks = {}, const std::string& record_path = "");

}  // namespace rayfarm
