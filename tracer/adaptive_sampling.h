// Adaptive supersampling after Rayshade's, which compares a pixel with its
// neighbours, on the corner samples of Whitted's. A pixel's full estimate is
// the mean of its k x k grid of samples (spp = k * k, sampler.h). Adaptive mode
// first traces one eye ray through every pixel corner, the lattice points
// (i, j) for 0 <= i <= width, 0 <= j <= height, each shared by the four
// pixels that meet there. A pixel whose own corners and its neighbours'
// nearest corners all agree within a contrast threshold is the mean of its
// four corners; any other pixel traces its whole grid and gets the
// bits of a uniform render.
//
// Looking past the pixel's own corners matters: a feature smaller than a
// pixel that falls between one pixel's corners is often caught at a
// neighbour's. Every lattice sample is a pure function of its point, so the
// decision depends only on the scene, the settings and the pixel: a band of
// rows traces the corner rows just above and below it and gets the bytes of a
// full render.
#pragma once

#include "tracer/vec3.h"

namespace rayfarm {

// The range of each channel over a set of samples, grown one sample at a
// time, and Rayshade's contrast test on it (independent of the samples'
// order).
class ChannelRange {
 public:
  explicit ChannelRange(const Vec3& first) : lo_{first.x, first.y, first.z}, hi_{first.x, first.y, first.z} {}
  void add(const Vec3& v) {
    for (int ch = 0; ch < 3; ++ch) {
      lo_[ch] = v[ch] < lo_[ch] ? v[ch] : lo_[ch];
      hi_[ch] = v[ch] > hi_[ch] ? v[ch] : hi_[ch];
    }
  }
  // Whether some channel's Rayshade contrast (max - min) / (max + min)
  // exceeds `threshold` (> 0), compared as max - min > threshold (max + min)
  // to spare a division per channel and pixel; a channel whose max + min is
  // ~0 (black everywhere) never does.
  bool contrast_exceeds(double threshold) const {
    constexpr double kBlack = 1e-12;
    for (int ch = 0; ch < 3; ++ch) {
      const double sum = hi_[ch] + lo_[ch];
      if (sum > kBlack && hi_[ch] - lo_[ch] > threshold * sum) return true;
    }
    return false;
  }

 private:
  double lo_[3], hi_[3];
};

// Whether these samples disagree enough to refine: ChannelRange's contrast
// test over all of them. A threshold <= 0 means uniform sampling: always
// refine.
bool needs_refinement(const Vec3* samples, int count, double threshold);

// Whether a k x k grid at this contrast threshold is sampled adaptively: a
// threshold > 0 and more than one sample per pixel.
inline bool is_adaptive(int k, double threshold) { return threshold > 0 && k >= 2; }

// How much more a neighbour's corner must differ than the pixel's own corners
// among themselves: what a pixel's own corners cannot see -- a feature
// smaller than a pixel, between them -- shows at a neighbour's corner as a
// strong contrast, while mild ones there are shading that the pixel's own
// corners already sample. A contrast of non-negative values is at most 1,
// so from a threshold of 0.2 up only a pixel's own corners decide.
constexpr double kNeighbourContrastFactor = 5;

// Whether pixel (x, y) of a width x height image takes its whole grid: its
// four corners differ by more than `threshold`, or they and the eight nearest
// corners beyond its edges (the two nearest corners of each neighbour, those
// inside the image's lattice) by more than kNeighbourContrastFactor times
// that. `corner(i, j)` is the sample at lattice point (i, j).
template <class Corner>
bool neighbourhood_needs_refinement(int x, int y, int width, int height, double threshold, Corner&& corner) {
  ChannelRange range(corner(x, y));
  range.add(corner(x + 1, y));
  range.add(corner(x, y + 1));
  range.add(corner(x + 1, y + 1));
  if (range.contrast_exceeds(threshold)) return true;
  const auto add = [&](int i, int j) {
    if (i >= 0 && j >= 0 && i <= width && j <= height) range.add(corner(i, j));
  };
  for (int j = y; j <= y + 1; ++j) {
    add(x - 1, j);
    add(x + 2, j);
  }
  for (int i = x; i <= x + 1; ++i) {
    add(i, y - 1);
    add(i, y + 2);
  }
  return range.contrast_exceeds(threshold * kNeighbourContrastFactor);
}

// An unrefined pixel: the mean of its four corners, top left, top right,
// bottom left, bottom right.
template <class Corner>
Vec3 corner_mean(int x, int y, Corner&& corner) {
  Vec3 sum = corner(x, y);
  sum += corner(x + 1, y);
  sum += corner(x, y + 1);
  sum += corner(x + 1, y + 1);
  return sum / 4;
}

// The mean of `count` samples summed in order: a pixel's whole grid, in cell
// order.
inline Vec3 grid_mean(const Vec3* samples, int count) {
  Vec3 sum;
  for (int i = 0; i < count; ++i) sum += samples[i];
  return sum / count;
}

}  // namespace rayfarm
