// ImageOptions: see image_options.h.
#include "app/image_options.h"

#include <algorithm>
#include <cstdlib>
#include <string>

#include "app/finite_number.h"
#include "tracer/render_settings.h"

namespace rayfarm::cmd {
namespace {

// `--adaptive` without a value. At 0.1 rayfarm's adaptive renders of the
// SPD paper scenes (512x512) err less than Rayshade's adaptive default
// against each tracer's own 64-spp image on all five, for fewer eye rays
// (README, Speed); the step from 0.15 to 0.1 is in docs/speed.md.
constexpr const char* kDefaultContrast = "0.1";

// `--adaptive` takes its value optionally, so the parser hands it the next
// word whatever it is: `render --adaptive scene.nff -o x.png` would fail on
// "Could not convert". This says what happened and how to write it.
const CLI::Validator kContrastValue(
    [](std::string& value) -> std::string {
      char* end = nullptr;
      std::strtod(value.c_str(), &end);
      if (!value.empty() && end && *end == '\0') return "";
      return "\"" + value + "\" is not a contrast: --adaptive takes the next word as its value, so put it after "
             "the scene or write --adaptive=" + kDefaultContrast;
    },
    "");

}  // namespace

// The settings rule's perfect square (render_settings.h), said of --spp: the
// rule's own "spp must be a perfect square" named no option. A word that is
// no whole number, or one out of the option's range, is left to those checks,
// which say so.
const CLI::Validator& square_spp() {
  static const CLI::Validator check(
      [](std::string& value) -> std::string {
        char* end = nullptr;
        const long spp = std::strtol(value.c_str(), &end, 10);
        if (value.empty() || *end != '\0' || spp < 1 || spp > kMaxSpp) return "";
        if (is_perfect_square(static_cast<int>(spp))) return "";
        return "expected a perfect square k*k (1, 4, 9, 16, 25, ...), found " + value;
      },
      "");
  return check;
}

void ImageOptions::add_to(CLI::App* cmd, RenderOverrides& o) {
  // The settings rule's ranges (tracer/render_settings.h), checked here too so
  // that a bad value is named by its option.
  width_option_ = cmd->add_option("--width", width_, "image width (default: the scene's resolution)")
                      ->check(CLI::Range(1, kMaxImageSide));
  height_option_ = cmd->add_option("--height", height_, "image height (default: keeps the aspect ratio)")
                       ->check(CLI::Range(1, kMaxImageSide));
  options_ = {width_option_, height_option_};
  options_.push_back(cmd->add_option("--spp", o.spp, "samples per pixel on a k x k grid (a perfect square)")
                         ->capture_default_str()
                         ->check(CLI::Range(1, kMaxSpp))
                         ->check(square_spp()));
  options_.push_back(cmd->add_option("--depth", o.max_depth, "maximum ray-tree depth, eye ray = 1")
                         ->capture_default_str()
                         ->check(CLI::Range(1, kMaxDepth)));
  options_.push_back(cmd->add_option("--seed", o.seed, "sampler seed")->capture_default_str());
  options_.push_back(
      cmd->add_option("--cutoff", o.cutoff,
                      "skip reflection/refraction rays whose weight falls below this; 0 = full tree (Rayshade's "
                      "default, 0.002, weighs rays otherwise: README, Speed)")
          ->capture_default_str()
          ->check(finite_number(0, 1)));
  options_.push_back(cmd->add_option("--adaptive", o.adaptive_contrast,
                  "adaptive supersampling: one sample at every pixel corner first, all --spp where the contrast among "
                  "a pixel's corners exceeds this (or its neighbours' nearest corners, 5 times this); the value "
                  "shown is taken when none is given, and without --adaptive every pixel gets all --spp")
      ->expected(0, 1)
      ->default_str(kDefaultContrast)
      ->check(kContrastValue)
      ->check(finite_number(0, kMaxAdaptiveContrast)));
}

bool ImageOptions::any_given() const {
  return std::any_of(options_.begin(), options_.end(), [](const CLI::Option* o) { return o->count() > 0; });
}

void ImageOptions::apply_size(RenderOverrides& o) const {
  if (width_option_ && width_option_->count()) o.width = width_;
  if (height_option_ && height_option_->count()) o.height = height_;
}

}  // namespace rayfarm::cmd
