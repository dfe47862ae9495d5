// `rayfarm render --workers N`: the render command with the local farm
// (broker/farm_render_job.h), for rayfarm-farm.
#include <unistd.h>

#include "app/commands.h"
#include "broker/farm_render_job.h"

namespace rayfarm::cmd {

namespace {
RenderReport render_on_local_farm(const RenderJob& job, int workers, int threads, const RenderCallbacks& callbacks,
                                  const std::string& record_path) {
  LocalFarmOptions farm;
  farm.workers = workers;
  farm.threads = threads;
  // As the in-process render: a progress line only when a person watches; a
  // script's log gets the summary line and nothing of the broker's progress.
  farm.progress = isatty(STDERR_FILENO) != 0;
  return run_render_job_on_local_farm(job, farm, callbacks, record_path);
}
}  // namespace

void add_render_with_farm(CLI::App& app) { add_render(app, &render_on_local_farm); }

}  // namespace rayfarm::cmd
