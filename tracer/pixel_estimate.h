// The last step of a pixel: the mean of its samples, stored as float RGB.
// A sample the integrator returns as NaN or Inf is a bug to be seen, not
// hidden: it is counted in RayStats::non_finite (reported in the stats and
// warned about after the render), and only the stored mean is made finite, so
// image files stay valid while every "no NaN" test can check the raw count.
#pragma once

#include <cmath>

#include "tracer/adaptive_sampling.h"
#include "tracer/ray_stats.h"
#include "tracer/vec3.h"

namespace rayfarm {

// A channel as stored: non-finite values (already counted) become 0.
inline float stored_channel(double v) { return std::isfinite(v) ? static_cast<float>(v) : 0.0f; }

// Estimates one pixel with sample_pixel_batched() and writes its RGB to
// out[0..3), counting into stats.non_finite each sample `shade` returns with a
// NaN or Inf channel. `shade` is as for sample_pixel_batched().
template <class ShadeBatch>
void estimate_pixel(int k, double threshold, ShadeBatch&& shade, RayStats& stats, float* out) {
  const Vec3 mean = sample_pixel_batched(k, threshold, [&](const int* cells, int count, Vec3* rgb) {
    shade(cells, count, rgb);
    for (int i = 0; i < count; ++i) stats.non_finite += !is_finite(rgb[i]);
  });
  out[0] = stored_channel(mean.x);
  out[1] = stored_channel(mean.y);
  out[2] = stored_channel(mean.z);
}

}  // namespace rayfarm
