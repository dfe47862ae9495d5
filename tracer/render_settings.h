// RenderSettings: every knob that changes the pixels or how they are computed.
// A pixel's value is a function of (scene, settings, pixel) only; `threads`
// changes speed, never bytes.
#pragma once

#include <cstdint>
#include <string>

namespace rayfarm {

struct RenderSettings {
  int width = 512;        // defaults to the scene's `resolution`
  int height = 512;
  int spp = 16;           // samples per pixel, jittered on a k x k grid (k*k == spp)
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

}  // namespace rayfarm
