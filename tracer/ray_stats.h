// RayStats and EffectSet: what a render did, per ray kind, and what it could do.
// EffectSet is derived from the scene before rendering so the render loop skips
// ray kinds that cannot occur (no refraction without T > 0, and so on).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace rayfarm {

struct RayStats {
  uint64_t eye = 0;
  uint64_t eye_hit = 0;  // eye rays that hit geometry (Haines' "eye hit rays")
  uint64_t shadow = 0;
  uint64_t reflection = 0;
  uint64_t refraction = 0;
  // Eye samples whose colour came back NaN or Inf (pixel_estimate.h): always 0
  // in a correct render; not a ray kind, so not part of total().
  uint64_t non_finite = 0;

  RayStats& operator+=(const RayStats& o) {
    eye += o.eye; eye_hit += o.eye_hit; shadow += o.shadow;
    reflection += o.reflection; refraction += o.refraction;
    non_finite += o.non_finite;
    return *this;
  }
  uint64_t total() const { return eye + shadow + reflection + refraction; }
};

struct EffectSet {
  bool shadows = false;     // at least one light
  bool reflection = false;  // some primitive has Ks > 0 or T > 0 (total internal reflection)
  bool refraction = false;  // some primitive has T > 0
  bool smooth_normals = false;  // some `pp` patch

  // Names in a fixed order, e.g. {"shadows", "reflection"}, for stats JSON.
  std::vector<std::string> names() const {
    std::vector<std::string> out;
    if (shadows) out.push_back("shadows");
    if (reflection) out.push_back("reflection");
    if (refraction) out.push_back("refraction");
    if (smooth_normals) out.push_back("smooth_normals");
    return out;
  }
};

}  // namespace rayfarm
