// Adaptive supersampling: Rayshade's contrast test.
#include "tracer/adaptive_sampling.h"

#include <algorithm>

namespace rayfarm {

double max_contrast(const Vec3* samples, int count) {
  // Below this a channel is black in every sample; (max - min) / (max + min)
  // would be 0/0 there, and black neighbourhoods need no refinement.
  constexpr double kBlack = 1e-12;
  double worst = 0;
  for (int ch = 0; ch < 3; ++ch) {
    double lo = samples[0][ch], hi = samples[0][ch];
    for (int i = 1; i < count; ++i) {
      lo = std::min(lo, samples[i][ch]);
      hi = std::max(hi, samples[i][ch]);
    }
    const double denom = hi + lo;
    if (denom > kBlack) worst = std::max(worst, (hi - lo) / denom);
  }
  return worst;
}

bool needs_refinement(const Vec3* samples, int count, double threshold) {
  if (threshold <= 0) return true;
  ChannelRange range(samples[0]);
  for (int i = 1; i < count; ++i) range.add(samples[i]);
  return range.contrast_exceeds(threshold);
}

}  // namespace rayfarm
