// RenderSettings: every knob that changes the pixels or how they are computed.
// A pixel's value is a function of (scene, settings, pixel) only; `threads`
// changes speed, never bytes. validate_settings() is the one rule for what a
// renderable setting is: `render`, the broker, the protocol decoder and the
// worker's renderer all call it, so no path can accept what another refuses.
#pragma once

#include <cstdint>
#include <string>

namespace rayfarm {

struct RenderSettings {
  int width = 512;        // defaults to the scene's `resolution`
  int height = 512;
  int spp = 16;           // samples per pixel, on a k x k grid (k*k == spp; sampler.h)
  int max_depth = 5;      // eye ray = depth 1 (SPD convention)
  int threads = 0;        // 0 = all hardware threads
  // Caps Embree's kernel width (EmbreeOptions::max_isa); like `threads` a
  // property of the machine, changing speed, never bytes, and not transmitted.
  std::string max_isa;
  uint64_t seed = 0;      // mixed into every pixel's sampler seed
  // Adaptive supersampling (Rayshade-style): 0 = uniform spp. Otherwise a pixel
  // first takes a coarse sample set and refines to `spp` only where samples
  // disagree by more than this contrast.
  double adaptive_contrast = 0;
  // Ray-tree pruning (Rayshade's `cutoff`): a reflection or refraction ray is
  // not spawned when its weight (the product of the Ks / T factors on its path)
  // times the most any one hit can shade (whitted.h) is below this. 0 traces
  // the full tree, which Haines' ray-count invariants assume.
  double cutoff = 0;
  bool robust_bvh = false;  // Embree RTC_SCENE_FLAG_ROBUST (watertight traversal)
};

// The limits of validate_settings (protocol/SPEC.md states them too).
inline constexpr int kMaxImageSide = 65536;
inline constexpr int kMaxSpp = 65536;  // 256 x 256
inline constexpr int kMaxDepth = 64;
inline constexpr int kMaxThreads = 4096;
inline constexpr double kMaxAdaptiveContrast = 1e30;

// True when n = k*k for a whole k: the samples of a pixel fill a k x k grid.
bool is_perfect_square(int n);

// Throws InputError naming the setting, e.g. "spp must be a perfect square k*k
// (1, 4, 9, 16, 25, ...), found 10". width/height in [1, 65536], spp a square
// in [1, 65536], max_depth in [1, 64], threads in [0, 4096], adaptive_contrast
// finite and in [0, 1e30].
void validate_settings(const RenderSettings& settings);

// True when `a` and `b` give the same pixels: every field but `threads` and
// `max_isa` (the machine's business) is equal.
bool same_pixels(const RenderSettings& a, const RenderSettings& b);

}  // namespace rayfarm
