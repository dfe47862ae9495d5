// `rayfarm broker`: the head node of a farm. Binds the worker and announce
// sockets, renders one scene with whichever workers connect (`rayfarm worker
// --connect ...` on each machine), writes the image and the job record. The job
// is prepared exactly as `rayfarm render` prepares it (broker/farm_render_job.h).

#include "app/commands.h"
#include "broker/broker_config.h"
#include "broker/farm_render_job.h"

namespace rayfarm::cmd {

void add_broker(CLI::App& app) {
  auto* sub = app.add_subcommand("broker", "render a scene on a farm of `rayfarm worker` processes");
  struct Options {
    RenderJob job;
    BrokerJobOptions farm;
    std::string config, bind, announce;
    int width = 0, height = 0, base_rows = 0, min_workers = -1, heartbeat_ms = 0, liveness = 0;
    double reference_weight = 0;
    bool no_progress = false;
  };
  auto o = std::make_shared<Options>();
  RenderOverrides& r = o->job.overrides;
  sub->add_option("scene", o->job.scene_path, "NFF scene file")->required();
  sub->add_option("-o,--output", o->job.output_path, "output image: .png/.tif (8-bit, linear) or .exr (float)")
      ->required();
  sub->add_option("--stats", o->job.stats_path, "write render statistics as JSON to this file");
  sub->add_option("--config", o->config, "broker config JSON (configs/broker.json)");
  sub->add_option("--record", o->farm.record_path, "write the job record (JSON) here");
  sub->add_option("--bind", o->bind, "worker endpoint to bind (default tcp://*:5555)");
  sub->add_option("--announce", o->announce, "announce endpoint to bind (default tcp://*:5556)");
  CLI::Option* width = sub->add_option("--width", o->width, "image width (default: the scene's resolution)");
  CLI::Option* height = sub->add_option("--height", o->height, "image height (default: keeps the aspect ratio)");
  sub->add_option("--spp", r.spp, "samples per pixel on a k x k grid (a perfect square)")->capture_default_str();
  sub->add_option("--depth", r.max_depth, "maximum ray-tree depth, eye ray = 1")->capture_default_str();
  sub->add_option("--seed", r.seed, "sampler seed")->capture_default_str();
  sub->add_option("--base-rows", o->base_rows, "scanlines per task at the reference weight")->check(CLI::Range(1, 65536));
  sub->add_option("--reference-weight", o->reference_weight, "weight that gets base-rows per task")
      ->check(CLI::Range(1e-6, 1e6));
  sub->add_option("--min-workers", o->min_workers, "workers to wait for before starting")->check(CLI::Range(0, 1 << 20));
  sub->add_option("--heartbeat-ms", o->heartbeat_ms, "heartbeat interval")->check(CLI::Range(10, 600000));
  sub->add_option("--liveness", o->liveness, "missed heartbeats before a worker is lost")->check(CLI::Range(1, 100));
  sub->add_flag("--shutdown-workers", o->farm.shutdown_workers, "tell the workers to exit when done");
  sub->add_flag("--no-progress", o->no_progress, "no progress line");
  sub->callback([o, width, height] {
    BrokerConfig& cfg = o->farm.config;
    if (!o->config.empty()) cfg = load_broker_config(o->config);
    if (!o->bind.empty()) cfg.bind = o->bind;
    if (!o->announce.empty()) cfg.announce_bind = o->announce;
    if (o->base_rows > 0) cfg.base_task_rows = o->base_rows;
    if (o->reference_weight > 0) cfg.reference_weight = o->reference_weight;
    if (o->min_workers >= 0) cfg.min_workers = o->min_workers;
    if (o->heartbeat_ms > 0) cfg.heartbeat_ms = o->heartbeat_ms;
    if (o->liveness > 0) cfg.liveness = o->liveness;
    if (o->no_progress) cfg.progress = false;
    if (width->count()) o->job.overrides.width = o->width;
    if (height->count()) o->job.overrides.height = o->height;

    o->farm.listening = [](const Broker& broker) {
      std::fprintf(stderr, "rayfarm broker: workers connect to %s (announcements on %s)\n",
                   broker.endpoint().c_str(), broker.announce_endpoint().c_str());
    };
    RenderCallbacks callbacks;
    callbacks.warning = [](const std::string& w) { std::fprintf(stderr, "warning: %s\n", w.c_str()); };
    const RenderReport report = run_render_job_on_broker(o->job, o->farm, callbacks);
    std::fprintf(stderr, "rayfarm broker: wrote %s (%.2f s)\n", o->job.output_path.c_str(), report.seconds.render);
  });
}

}  // namespace rayfarm::cmd
