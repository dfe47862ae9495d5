// Adaptive supersampling: the coarse cell set and Rayshade's contrast test.
#include "tracer/adaptive_sampling.h"

#include <algorithm>

namespace rayfarm {

CoarseCells coarse_cells(int k) {
  CoarseCells out;
  if (k <= 1) {
    out.index[0] = 0;
    out.count = 1;
    return out;
  }
  // Corners of the grid, ascending in row-major order: they span the pixel as
  // SPD corner sampling does, so an edge crossing the pixel separates them.
  const int last = k - 1;
  out.index = {0, last, last * k, last * k + last};
  out.count = 4;
  return out;
}

CoarseCells first_cells(int k, double threshold) {
  if (k <= 2) {  // the whole grid, ascending
    CoarseCells all;
    all.count = k * k;
    for (int c = 0; c < all.count; ++c) all.index[c] = c;
    return all;
  }
  return threshold > 0 ? coarse_cells(k) : CoarseCells{};
}

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

bool needs_refinement(const Vec3* coarse, int count, double threshold) {
  if (threshold <= 0) return true;
  return max_contrast(coarse, count) > threshold;
}

}  // namespace rayfarm
