// `rayfarm broker`: the head node of a farm. Binds the worker and announce
// sockets, renders one scene with whichever workers connect (`rayfarm worker
// --connect ...` on each machine), writes the image and the job record.

#include "app/commands.h"
#include "broker/broker.h"
#include "broker/broker_config.h"
#include "protocol/codec.h"
#include "tracer/image_io.h"
#include "tracer/nff_reader.h"
#include "tracer/text_file.h"

namespace rayfarm::cmd {

void add_broker(CLI::App& app) {
  auto* sub = app.add_subcommand("broker", "render a scene on a farm of `rayfarm worker` processes");
  struct Options {
    std::string scene, output, config, record, bind, announce, policy;
    int width = 0, height = 0, spp = 16, depth = 5, base_rows = 0, min_workers = -1, heartbeat_ms = 0, liveness = 0;
    uint64_t seed = 0;
    double reference_weight = 0;
    bool shutdown_workers = false, no_progress = false;
  };
  auto o = std::make_shared<Options>();
  sub->add_option("scene", o->scene, "NFF scene file")->required()->check(CLI::ExistingFile);
  sub->add_option("-o,--output", o->output, "output image (.png, .exr, ...)")->required();
  sub->add_option("--config", o->config, "broker config JSON (configs/broker.json)")->check(CLI::ExistingFile);
  sub->add_option("--record", o->record, "write the job record (JSON) here");
  sub->add_option("--bind", o->bind, "worker endpoint to bind (default tcp://*:5555)");
  sub->add_option("--announce", o->announce, "announce endpoint to bind (default tcp://*:5556)");
  sub->add_option("--width", o->width, "image width (default: the scene's resolution)")->check(CLI::Range(1, 65536));
  sub->add_option("--height", o->height, "image height (default: the scene's resolution)")->check(CLI::Range(1, 65536));
  sub->add_option("--spp", o->spp, "samples per pixel (a square number)")->capture_default_str()->check(CLI::Range(1, 65536));
  sub->add_option("--depth", o->depth, "maximum ray depth (eye ray = 1)")->capture_default_str()->check(CLI::Range(1, 64));
  sub->add_option("--seed", o->seed, "sampler seed");
  sub->add_option("--base-rows", o->base_rows, "scanlines per task at the reference weight")->check(CLI::Range(1, 65536));
  sub->add_option("--policy", o->policy, std::string("dispatch policy: ") + kPolicyNames + " (default adaptive)");
  sub->add_option("--reference-weight", o->reference_weight, "weight that gets base-rows per task")
      ->check(CLI::Range(1e-6, 1e6));
  sub->add_option("--min-workers", o->min_workers, "workers to wait for before starting")->check(CLI::Range(0, 1 << 20));
  sub->add_option("--heartbeat-ms", o->heartbeat_ms, "heartbeat interval")->check(CLI::Range(10, 600000));
  sub->add_option("--liveness", o->liveness, "missed heartbeats before a worker is lost")->check(CLI::Range(1, 100));
  sub->add_flag("--shutdown-workers", o->shutdown_workers, "tell the workers to exit when done");
  sub->add_flag("--no-progress", o->no_progress, "no progress line");
  sub->callback([o] {
    BrokerConfig cfg = o->config.empty() ? BrokerConfig{} : load_broker_config(o->config);
    if (!o->bind.empty()) cfg.bind = o->bind;
    if (!o->announce.empty()) cfg.announce_bind = o->announce;
    if (o->base_rows > 0) cfg.base_task_rows = o->base_rows;
    if (o->reference_weight > 0) cfg.reference_weight = o->reference_weight;
    if (!o->policy.empty()) cfg.policy = parse_policy(o->policy, "--policy");
    if (o->min_workers >= 0) cfg.min_workers = o->min_workers;
    if (o->heartbeat_ms > 0) cfg.heartbeat_ms = o->heartbeat_ms;
    if (o->liveness > 0) cfg.liveness = o->liveness;
    if (o->no_progress) cfg.progress = false;

    FarmJob job;
    job.scene_text = read_text_file(o->scene);
    job.scene_name = o->scene;
    const Scene scene = parse_nff(job.scene_text, o->scene);  // bad scenes fail here, not on every worker
    job.settings.width = o->width ? o->width : scene.camera.width;
    job.settings.height = o->height ? o->height : scene.camera.height;
    job.settings.spp = o->spp;
    job.settings.max_depth = o->depth;
    job.settings.seed = o->seed;

    Broker broker(cfg);
    std::fprintf(stderr, "rayfarm broker: workers connect to %s (announcements on %s)\n", broker.endpoint().c_str(),
                 broker.announce_endpoint().c_str());
    const FarmResult r = broker.run(job);
    write_image(o->output, r.width, r.height, r.rgb);
    if (!o->record.empty()) write_json_file(o->record, r.record);
    if (o->shutdown_workers) broker.shutdown_workers();
    std::fprintf(stderr, "rayfarm broker: wrote %s (%.2f s, %d tasks)\n", o->output.c_str(),
                 r.record["total_s"].get<double>(), r.record["task_count"].get<int>());
  });
}

}  // namespace rayfarm::cmd
