// Adaptive supersampling: Rayshade's contrast test.
#include "tracer/adaptive_sampling.h"

namespace rayfarm {

bool needs_refinement(const Vec3* samples, int count, double threshold) {
  if (threshold <= 0) return true;
  ChannelRange range(samples[0]);
  for (int i = 1; i < count; ++i) range.add(samples[i]);
  return range.contrast_exceeds(threshold);
}

}  // namespace rayfarm
