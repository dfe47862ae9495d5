// `rayfarm render SCENE.nff -o OUT.png [...]`: parses options into a RenderJob
// (tracer/render_job.h) and reports; the work happens there. `--workers N`
// renders on a local farm, which only rayfarm-farm links (app/main.cpp).
#include <unistd.h>

#include <cstdio>
#include <memory>
#include <stdexcept>
#include <string>

#include "app/commands.h"
#include "app/image_options.h"
#include "tracer/embree_scene.h"
#include "tracer/error.h"
#include "tracer/interrupt_cleanup.h"
#include "tracer/render_job.h"
#include "tracer/render_settings.h"

namespace rayfarm::cmd {
namespace {

struct RenderCommand {
  LocalFarmRender farm_render = nullptr;
  RenderJob job;
  ImageOptions image;
  std::string rows;
  int workers = 0;          // > 0: render on that many local worker processes
  std::string farm_record;  // with workers: the farm's job record
};

// One carriage-return line on stderr, only when a person is watching.
ProgressFn terminal_progress(const std::string& scene) {
  if (!isatty(STDERR_FILENO)) return {};
  return [scene](int done, int total) {
    std::fprintf(stderr, "\rrendering %s: %3d%% (%d/%d rows)", scene.c_str(), total ? 100 * done / total : 100,
                 done, total);
    if (done == total) std::fputc('\n', stderr);
    std::fflush(stderr);
  };
}

void run(RenderCommand& c) {
  c.image.apply_size(c.job.overrides);
  if (!c.rows.empty()) c.job.rows = parse_rows(c.rows);
  RenderCallbacks callbacks;
  callbacks.warning = [](const std::string& w) { std::fprintf(stderr, "warning: %s\n", w.c_str()); };
  callbacks.progress = terminal_progress(c.job.scene_path);
  if (c.workers > 0 && !c.farm_render) throw std::logic_error("render --workers reached a program without the farm");
  // Here, not only where the tracer starts: each local farm worker would refuse it on its own.
  check_embree_isa(c.job.overrides.max_isa, "--max-isa");
  // Only a farm keeps a job record; without one the file would silently never appear.
  if (!c.farm_record.empty() && c.workers == 0)
    throw InputError("--farm-record " + c.farm_record + ": a job record is the farm's; add --workers N");
  // Ctrl-C or SIGTERM: no half-written temporary left beside -o, nor beside
  // --stats or --farm-record. A local farm's workers die with this process
  // (broker/child_process.h).
  remove_temporaries_on_interrupt();
  const RenderReport r = c.workers > 0 ? c.farm_render(c.job, c.workers, c.job.overrides.threads, callbacks, c.farm_record)
                                       : run_render_job(c.job, callbacks);
  const double mrays = stats_json(r)["mrays_per_s"].get<double>();
  std::printf("%s: %dx%d rows %d:%d, %d spp, depth %d; parse %.3f s, build %.3f s, render %.3f s, %.2f Mrays/s\n",
              c.job.output_path.c_str(), r.settings.width, r.rows.count(), r.rows.y0, r.rows.y1, r.settings.spp,
              r.settings.max_depth, r.seconds.parse, r.seconds.build, r.seconds.render, mrays);
}

}  // namespace

void add_render(CLI::App& app, LocalFarmRender farm_render) {
  auto c = std::make_shared<RenderCommand>();
  c->farm_render = farm_render;
  RenderOverrides& o = c->job.overrides;
  CLI::App* cmd = app.add_subcommand("render", "render an NFF scene to an image");
  cmd->add_option("scene", c->job.scene_path, "NFF scene file")->required();
  cmd->add_option("-o,--output", c->job.output_path, "output image: .png/.tif (8-bit, linear) or .exr (float)")
      ->required();
  c->image.add_to(cmd, o);
  cmd->add_option("--threads", o.threads, "threads, 0 = all")->capture_default_str()->check(CLI::Range(0, kMaxThreads));
  cmd->add_option("--max-isa", o.max_isa,
                  "cap the SIMD kernel width (Embree's and rayfarm's): sse2, sse4.2, avx, avx2 or avx512 "
                  "(same pixels, for tests and timing)");
  cmd->add_option("--rows", c->rows, "render only rows Y0:Y1; the image is Y1-Y0 rows high");
  cmd->add_option("--stats", c->job.stats_path, "write render statistics as JSON to this file");
  cmd->add_option("--workers", c->workers, "render on N local worker processes; 0 = in this process")
      ->capture_default_str()->check(CLI::Range(0, 4096));
  cmd->add_option("--farm-record", c->farm_record, "with --workers: write the farm's job record (JSON) here");
  cmd->callback([c] { run(*c); });
}

}  // namespace rayfarm::cmd
