// The last step of a pixel: the mean of its samples, stored as float RGB.
// A sample the integrator returns as NaN or Inf is a bug to be seen, not
// hidden: it is counted in RayStats::non_finite (reported in the stats and
// warned about after the render), and only the stored mean is made finite, so
// image files stay valid while every "no NaN" test can check the raw count.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>

#include "tracer/ray_stats.h"
#include "tracer/vec3.h"

namespace rayfarm {

// A channel as stored: non-finite values (already counted) become 0, and
// finite ones past float's range the largest float of their sign. Scene
// numbers up to kMaxSceneMagnitude multiply (light x colour x Kd ~ 1e48): the
// plain cast made such a sample Inf in an EXR, uncounted.
inline float stored_channel(double v) {
  if (!std::isfinite(v)) return 0.0f;
  constexpr double kFloatMax = std::numeric_limits<float>::max();
  return static_cast<float>(std::clamp(v, -kFloatMax, kFloatMax));
}

// Counts into stats.non_finite the samples with a NaN or Inf channel.
inline void count_non_finite(const Vec3* rgb, int count, RayStats& stats) {
  for (int i = 0; i < count; ++i) stats.non_finite += !is_finite(rgb[i]);
}

// Writes a pixel's mean to out[0..3), as stored.
inline void store_mean(const Vec3& mean, float* out) {
  out[0] = stored_channel(mean.x);
  out[1] = stored_channel(mean.y);
  out[2] = stored_channel(mean.z);
}

}  // namespace rayfarm
