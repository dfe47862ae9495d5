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

// `shade` (as for finish_pixel()), counting what it returns with count_non_finite().
template <class ShadeBatch>
auto counted(ShadeBatch& shade, RayStats& stats) {
  return [&shade, &stats](const int* cells, int count, Vec3* rgb) {
    shade(cells, count, rgb);
    count_non_finite(rgb, count, stats);
  };
}

// Estimates one pixel with sample_pixel_batched() and writes its RGB to
// out[0..3), counting into stats.non_finite each sample `shade` returns with a
// NaN or Inf channel.
template <class ShadeBatch>
void estimate_pixel(int k, double threshold, ShadeBatch&& shade, RayStats& stats, float* out) {
  store_mean(sample_pixel_batched(k, threshold, counted(shade, stats)), out);
}

// The same from the pixel's first cells (`coarse`, first_cells()) and their
// values, traced and counted by the caller with other pixels' first cells:
// finish_pixel().
template <class ShadeBatch>
void finish_estimate(int k, double threshold, const CoarseCells& coarse, const Vec3* first, ShadeBatch&& shade,
                     RayStats& stats, float* out) {
  store_mean(finish_pixel(k, threshold, coarse, first, counted(shade, stats)), out);
}

}  // namespace rayfarm
