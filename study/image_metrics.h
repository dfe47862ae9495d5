// Image metrics for the accuracy study and the accuracy tests: RMSE, PSNR,
// maximum and mean absolute error between two float RGB images of one size,
// and a finiteness check. Images are the renderer's layout: row-major, top row
// first, 3 floats per pixel, linear values with display white at 1.
#pragma once

#include <cstddef>
#include <vector>

namespace rayfarm {

struct ImageDiff {
  double rmse = 0;      // root mean square over all channels
  double psnr = 0;      // 20 log10(peak / rmse) dB, peak = 1; +inf for equal images
  double max_abs = 0;   // largest per-channel absolute difference
  double mean_abs = 0;  // mean per-channel absolute difference
  size_t pixels_over = 0;  // pixels with some channel differing by more than `tolerance`
};

struct DiffOptions {
  // Compare what a display shows: values clamped to [0, 1] first, so a
  // highlight at 3.0 vs 2.0 (both white on screen) is no error.
  bool clamp = true;
  double tolerance = 1.0 / 255;  // for ImageDiff::pixels_over
};

// Throws std::invalid_argument when the sizes differ or are not a multiple of 3.
ImageDiff compare_images(const std::vector<float>& a, const std::vector<float>& b,
                         const DiffOptions& options = {});

// PSNR in dB for a given RMSE and peak (Gonzalez & Woods); +inf for rmse == 0.
double psnr_from_rmse(double rmse, double peak = 1.0);

// Number of NaN or infinite values; 0 for a healthy render.
size_t count_non_finite(const std::vector<float>& rgb);
inline bool all_finite(const std::vector<float>& rgb) { return count_non_finite(rgb) == 0; }

// Number of pixels that are exactly black (all three channels 0): speckle from
// self-intersection or holes shows up here.
size_t count_black_pixels(const std::vector<float>& rgb);

}  // namespace rayfarm
