// Render jobs on farms; see farm_render_job.h.
#include "broker/farm_render_job.h"

#include <algorithm>

#include "tracer/error.h"
#include "tracer/output_file.h"
#include "tracer/renderer.h"
#include "tracer/text_file.h"
#include "tracer/whitted.h"

namespace rayfarm {
namespace {

// Parsed on the broker too, so scene errors surface once, not in every worker.
// The job record (`record_option`, e.g. "--record"; an empty path: none) is
// checked with the job's other files, before any work.
PreparedJob prepare_farm_job(const RenderJob& job, const RenderCallbacks& callbacks, const std::string& record_option,
                             const std::string& record_path) {
  if (job.rows) throw InputError("--rows renders a band in this process; it cannot be used on a farm");
  check_distinct_files({{"the scene", job.scene_path}, {"-o", job.output_path}, {"--stats", job.stats_path},
                        {record_option, record_path}});
  PreparedJob p = prepare_render_job(job, callbacks);
  if (!record_path.empty()) check_output_path(record_path);
  p.report.effects = derive_effects(p.scene);
  return p;
}

// Workers whose render threads together outnumber the threads the machine
// runs at once only share its cores, each loading the scene and building its
// BVH: said once, as for --threads, since the render is slower, not faster (64
// workers on 2 cores took some 6 times as long as 2, without a word). Each
// worker renders on --threads threads, on every one the machine runs when 0:
// two such workers already share them all.
void warn_of_idle_workers(const LocalFarmOptions& options, const RenderCallbacks& callbacks) {
  const int workers = options.machines.empty() ? options.workers : static_cast<int>(options.machines.size());
  const int machine = render_threads(0);
  const int each = render_threads(options.threads);
  const long long threads = static_cast<long long>(workers) * each;
  if (threads <= machine || !callbacks.warning) return;
  const std::string m = std::to_string(machine);
  const std::string each_said = options.threads == 0         ? " (all " + m + " of this machine's threads each)"
                                : options.threads > machine ? " (" + m + " each, all this machine runs)"
                                                            : "";
  // Fewer workers than threads: a --threads that shares the machine out.
  const std::string advice =
      workers <= machine ? "; --threads " + std::to_string(machine / workers) + " gives each worker its share" : "";
  callbacks.warning("--workers " + std::to_string(workers) + " with --threads " + std::to_string(options.threads) +
                    each_said + ": " + std::to_string(threads) + " render threads, and this machine runs " + m +
                    " at once; the workers share them and render no faster than " + m + " threads would" + advice);
}

// The farm's rays and times into the report, then the image, stats and record.
void finish_farm_job(const RenderJob& job, RenderReport& report, const RayStats& stats,
                     const nlohmann::json& record, const std::vector<float>& rgb, const std::string& record_path,
                     const RenderCallbacks& callbacks) {
  report.rays = stats;
  report.seconds.render = record["total_s"].get<double>();
  for (const auto& w : record["workers"]) report.seconds.build = std::max(report.seconds.build, w["init_s"].get<double>());
  // The threads that rendered the image, as its rays and Mrays/s are the
  // farm's: not this process's cores (a broker renders nothing), nor one worker's.
  report.settings.threads = 0;
  for (const auto& w : record["workers"])
    if (w["tasks"].get<int>() > 0) report.settings.threads += w["threads"].get<int>();
  finish_render_job(job, report, rgb, callbacks);
  if (!record_path.empty()) write_json_file(record_path, record);
}

// On the way out of a failed job: the job's own error is the one to report.
void shutdown_workers_quietly(Broker& broker) noexcept {
  try {
    broker.shutdown_workers();
  } catch (...) {
  }
}

}  // namespace

RenderReport run_render_job_on_local_farm(const RenderJob& job, const LocalFarmOptions& options,
                                          const RenderCallbacks& callbacks, const std::string& record_path) {
  PreparedJob p = prepare_farm_job(job, callbacks, "--farm-record", record_path);
  warn_of_idle_workers(options, callbacks);
  const LocalFarmResult farm = render_local_farm(p.scene_text, job.scene_path, p.report.settings, options);
  finish_farm_job(job, p.report, farm.stats, farm.record, farm.rgb, record_path, callbacks);
  return p.report;
}

RenderReport run_render_job_on_broker(const RenderJob& job, const BrokerJobOptions& options,
                                      const RenderCallbacks& callbacks) {
  PreparedJob p = prepare_farm_job(job, callbacks, "--record", options.record_path);
  BrokerConfig config = options.config;
  config.max_image_width = p.report.settings.width;  // the frame cap follows the job
  Broker broker(config, options.log);
  if (options.listening) options.listening(broker);
  // The workers are told to exit as soon as the job is over, before the image
  // is written and also when the job fails: told only after a successful
  // write, workers started for this one job outlived a broker that could not
  // write -o, waiting for it forever.
  FarmResult farm;
  try {
    farm = broker.run(FarmJob{p.scene_text, job.scene_path, p.report.settings});
  } catch (...) {
    if (options.shutdown_workers) shutdown_workers_quietly(broker);
    throw;
  }
  if (options.shutdown_workers) broker.shutdown_workers();
  finish_farm_job(job, p.report, farm.stats, farm.record, farm.rgb, options.record_path, callbacks);
  return p.report;
}

}  // namespace rayfarm
