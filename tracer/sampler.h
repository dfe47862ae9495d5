// Where a pixel's samples fall. Every sample position is a pure function of
// (seed, pixel x, pixel y, cell), so a pixel's value never depends on which
// thread, band or order rendered it, nor on which other cells were traced
// (adaptive sampling may skip cells). Samples sit on a k x k jittered grid.
#pragma once

#include <cmath>
#include <cstdint>

namespace rayfarm {

// SplitMix64 finaliser (Steele, Lea & Flood 2014): a bijective 64-bit mixer
// whose outputs pass BigCrush even for consecutive inputs.
constexpr uint64_t mix64(uint64_t z) {
  z += 0x9E3779B97F4A7C15ull;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

// Hash of everything a pixel's randomness may depend on; a sample adds its cell.
constexpr uint64_t pixel_key(uint64_t seed, int x, int y) {
  uint64_t h = mix64(seed);
  h = mix64(h ^ static_cast<uint32_t>(x));
  return mix64(h ^ (static_cast<uint64_t>(static_cast<uint32_t>(y)) << 32));
}
constexpr uint64_t sample_hash(uint64_t seed, int x, int y, int cell) {
  return mix64(pixel_key(seed, x, y) ^ static_cast<uint32_t>(cell));
}

// 24 high bits -> a float-exact double in [0, 1).
constexpr double unit_double(uint64_t bits) { return static_cast<double>(bits >> 40) * (1.0 / 16777216.0); }

// Smallest k with k*k >= spp; the renderer requires spp to be a perfect square.
inline int grid_size(int spp) {
  int k = static_cast<int>(std::lround(std::sqrt(static_cast<double>(spp))));
  while (k * k < spp) ++k;
  return k;
}

struct PixelSample {
  double x, y;  // position inside the pixel, each in [0, 1)
};

// Cell `cell` (row-major in the k x k grid) of pixel (x, y). One sample per
// pixel (k == 1) takes the pixel centre, like a classical single-ray tracer;
// k > 1 jitters uniformly inside each cell (stratified sampling).
// `key` is pixel_key(seed, x, y), computed once per pixel.
inline PixelSample jittered_sample(uint64_t key, int cell, int k) {
  if (k <= 1) return {0.5, 0.5};
  const uint64_t h = mix64(key ^ static_cast<uint32_t>(cell));
  const double jx = unit_double(h), jy = unit_double(mix64(h));
  const int cx = cell % k, cy = cell / k;
  return {(cx + jx) / k, (cy + jy) / k};
}
inline PixelSample jittered_sample(uint64_t seed, int x, int y, int cell, int k) {
  return jittered_sample(pixel_key(seed, x, y), cell, k);
}

}  // namespace rayfarm
