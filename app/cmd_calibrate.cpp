// `rayfarm calibrate`: times a reference render on this machine and writes a
// worker config whose weight is on the SPECfp92 scale of configs/workers
// (worker/calibration.h says how the scale is anchored).
#include <cstdio>

#include "app/commands.h"
#include "app/image_options.h"
#include "tracer/output_file.h"
#include "tracer/text_file.h"
#include "worker/calibration.h"

namespace rayfarm::cmd {

void add_calibrate(CLI::App& app) {
  auto* sub = app.add_subcommand("calibrate", "measure this machine's render speed; write a worker config with its weight");
  struct Options {
    CalibrationSpec spec;
    std::string output;
  };
  auto o = std::make_shared<Options>();
  sub->add_option("-o,--output", o->output, "worker config to write (JSON, as configs/workers/*.json)")->required();
  sub->add_option("--threads", o->spec.threads, "render threads the worker will use (0 = all cores)")
      ->capture_default_str()->check(CLI::Range(0, 4096));
  sub->add_option("--size", o->spec.width, "reference image is SIZE x SIZE")->capture_default_str()->check(CLI::Range(8, 4096));
  sub->add_option("--spp", o->spec.spp, "samples per pixel (a square number)")->capture_default_str()
      ->check(CLI::Range(1, 1024))
      ->check(square_spp());
  sub->add_option("--repeats", o->spec.repeats, "renders; the fastest counts")->capture_default_str()->check(CLI::Range(1, 100));
  sub->callback([o] {
    o->spec.height = o->spec.width;
    check_output_path(o->output);  // before the renders, and with the reason
    const Calibration c = calibrate(o->spec);
    if (!c.warning.empty()) std::fprintf(stderr, "rayfarm: warning: %s\n", c.warning.c_str());
    write_json_file(o->output, calibrated_worker_config(c));
    std::printf("%s\nwrote %s\n", c.description.c_str(), o->output.c_str());
  });
}

}  // namespace rayfarm::cmd
