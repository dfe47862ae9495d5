// Spawning secondary rays without self-intersection and without a fixed epsilon.
// Wachter & Binder, "A Fast and Robust Method for Avoiding Self-Intersection"
// (Ray Tracing Gems ch. 6): move the hit point a few float ULPs along the
// geometric normal, scaled to the magnitude of its coordinates, so the offset is
// right at every scene scale. Works on the float positions Embree traces.
// WB's two absolute constants (the size of the region around the origin where a
// plain float offset is used, and that offset) assume magnitudes ~1; here they
// are given in units of the hit's own magnitude, max(|p|, |ray origin|) (the
// rounding error of p = o + t*d is relative to both), so scaling a scene by
// 1e-3 or 1e3 scales every offset with it, and far-away geometry elsewhere in
// the scene changes nothing.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>

#include "tracer/vec3.h"

namespace rayfarm {

namespace detail {
inline float offset_component(float p, float n, float scale) {
  // Constants from Ray Tracing Gems ch. 6: near the origin a float offset,
  // elsewhere an integer offset of the float's bit pattern.
  constexpr float kOrigin = 1.0f / 32.0f;
  constexpr float kFloatScale = 1.0f / 65536.0f;
  constexpr float kIntScale = 256.0f;
  if (std::fabs(p) < kOrigin * scale) return p + kFloatScale * scale * n;
  const int32_t of_i = static_cast<int32_t>(kIntScale * n);
  int32_t bits;
  std::memcpy(&bits, &p, sizeof bits);
  bits += (p < 0) ? -of_i : of_i;
  float out;
  std::memcpy(&out, &bits, sizeof out);
  return out;
}
}  // namespace detail

// The magnitude the offset is measured against for hit `p` of a ray from `org`:
// the largest |coordinate| of either (never below the smallest normal float).
inline double offset_scale(const Vec3& p, const Vec3& org) {
  // Plain comparisons: std::fmax is an out-of-line libm call on this hot path.
  double m = 1e-30;
  for (const double v : {p.x, p.y, p.z, org.x, org.y, org.z}) {
    const double a = std::fabs(v);
    m = a > m ? a : m;
  }
  return m;
}

// `p` is the hit point (rounded to float here, as Embree will see it), `n` the
// unit geometric normal pointing to the side the new ray leaves towards, and
// `scale` offset_scale() of the hit (1 reproduces the published constants).
inline Vec3 offset_ray_origin(const Vec3& p, const Vec3& n, double scale = 1.0) {
  const float s = static_cast<float>(scale);
  return {detail::offset_component(static_cast<float>(p.x), static_cast<float>(n.x), s),
          detail::offset_component(static_cast<float>(p.y), static_cast<float>(n.y), s),
          detail::offset_component(static_cast<float>(p.z), static_cast<float>(n.z), s)};
}

}  // namespace rayfarm
