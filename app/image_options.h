// The options of every command that starts a render (`render`, `broker`,
// `submit`): the image's size and its quality knobs, into RenderOverrides.
// One definition, so the three commands take the same flags, say the same in
// --help, and refuse the same values: the settings' rule (render_settings.h),
// checked here too so that a bad value is named by its option.
#pragma once

#include <CLI/CLI.hpp>
#include <vector>

#include "tracer/render_job.h"

namespace rayfarm::cmd {

// Refuses an --spp that is no perfect square, naming the option; for every
// command that takes a sample count (`render`, `calibrate`, `replay`).
const CLI::Validator& square_spp();

class ImageOptions {
 public:
  // Adds --width, --height, --spp, --depth, --seed, --cutoff and --adaptive
  // to `cmd`; all but the size write into `overrides`, which must outlive
  // the parse.
  void add_to(CLI::App* cmd, RenderOverrides& overrides);
  // Sets the size in `overrides` where it was given: otherwise the scene's
  // resolution stays, and a given 0 is refused like any bad width.
  void apply_size(RenderOverrides& overrides) const;
  // Whether any of them was given (`broker --serve` takes none: each job
  // brings its own).
  bool any_given() const;

 private:
  int width_ = 0, height_ = 0;
  CLI::Option* width_option_ = nullptr;
  CLI::Option* height_option_ = nullptr;
  std::vector<CLI::Option*> options_;  // all of them, the size's too
};

}  // namespace rayfarm::cmd
