// Render jobs on a farm: the same RenderJob (tracer/render_job.h) as an
// in-process render -- same preparation (outputs checked, scene read, settings
// derived and validated before any work), same image and stats JSON -- but the
// rows are rendered by farm workers. `rayfarm render --workers N` runs N local
// worker processes (broker/local_farm.h); `rayfarm broker` serves whichever
// workers connect. Either way the image is byte-identical to the in-process one.
#pragma once

#include <functional>
#include <string>

#include "broker/broker.h"
#include "broker/local_farm.h"
#include "tracer/render_job.h"

namespace rayfarm {

// Stats JSON seconds: parse = the broker's parse, build = the slowest worker's
// BVH build, render = announce to assembled image. `record_path` (optional)
// receives the farm's job record.
RenderReport run_render_job_on_local_farm(const RenderJob& job, const LocalFarmOptions& options,
                                          const RenderCallbacks& callbacks = {}, const std::string& record_path = "");

struct BrokerJobOptions {
  BrokerConfig config;
  std::string record_path;                         // "" = no job record file
  bool shutdown_workers = false;                   // tell the workers to exit afterwards
  LogSink log;                                     // {} = stderr
  std::function<void(const Broker&)> listening;    // called once the sockets are bound
};

// `rayfarm broker`: binds a broker sized for this job and renders it with the
// workers that connect. Throws InputError before binding when the job is bad.
RenderReport run_render_job_on_broker(const RenderJob& job, const BrokerJobOptions& options,
                                      const RenderCallbacks& callbacks = {});

}  // namespace rayfarm
