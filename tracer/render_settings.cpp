// The one render-settings rule; see render_settings.h.
#include "tracer/render_settings.h"

#include <cmath>
#include <cstdio>
#include <string>

#include "tracer/error.h"

namespace rayfarm {
namespace {

void check_range(const char* name, int value, int lo, int hi) {
  if (value < lo || value > hi)
    throw InputError(std::string(name) + " must be between " + std::to_string(lo) + " and " + std::to_string(hi) +
                     ", found " + std::to_string(value));
}

}  // namespace

bool is_perfect_square(int n) {
  const int k = static_cast<int>(std::lround(std::sqrt(static_cast<double>(n))));
  return k * k == n;
}

void validate_settings(const RenderSettings& s) {
  check_range("width", s.width, 1, kMaxImageSide);
  check_range("height", s.height, 1, kMaxImageSide);
  check_range("spp", s.spp, 1, kMaxSpp);
  if (!is_perfect_square(s.spp))
    throw InputError("spp must be a perfect square k*k (1, 4, 9, 16, 25, ...), found " + std::to_string(s.spp));
  check_range("depth", s.max_depth, 1, kMaxDepth);
  check_range("threads", s.threads, 0, kMaxThreads);
  if (!(s.adaptive_contrast >= 0 && s.adaptive_contrast <= kMaxAdaptiveContrast)) {
    // %g: std::to_string writes 1e308 out in 309 digits.
    char text[96];
    std::snprintf(text, sizeof text, "adaptive contrast must be a finite number >= 0 and <= %g, found %g",
                  kMaxAdaptiveContrast, s.adaptive_contrast);
    throw InputError(text);
  }
  if (!(s.cutoff >= 0 && s.cutoff <= 1)) {
    // %g as above: std::to_string wrote -0.5 as -0.500000.
    char text[96];
    std::snprintf(text, sizeof text, "cutoff must be between 0 and 1, found %g", s.cutoff);
    throw InputError(text);
  }
}

bool same_pixels(const RenderSettings& a, const RenderSettings& b) {
  return a.width == b.width && a.height == b.height && a.spp == b.spp && a.max_depth == b.max_depth &&
         a.seed == b.seed && a.adaptive_contrast == b.adaptive_contrast && a.cutoff == b.cutoff &&
         a.robust_bvh == b.robust_bvh;
}

}  // namespace rayfarm
