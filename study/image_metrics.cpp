// Image metrics: RMSE, PSNR, absolute errors and finiteness of float RGB images.
#include "study/image_metrics.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace rayfarm {

namespace {
double display_value(float v, bool clamp) {
  return clamp ? std::clamp(static_cast<double>(v), 0.0, 1.0) : static_cast<double>(v);
}
}  // namespace

double psnr_from_rmse(double rmse, double peak) {
  if (rmse <= 0) return std::numeric_limits<double>::infinity();
  return 20.0 * std::log10(peak / rmse);
}

ImageDiff compare_images(const std::vector<float>& a, const std::vector<float>& b,
                         const DiffOptions& options) {
  if (a.size() != b.size() || a.size() % 3 != 0) {
    throw std::invalid_argument("compare_images: sizes differ or are not RGB (" +
                                std::to_string(a.size()) + " vs " + std::to_string(b.size()) + ")");
  }
  ImageDiff d;
  if (a.empty()) {
    d.psnr = psnr_from_rmse(0);
    return d;
  }
  // Sum squares in double: a 1024x1024 image has 3M terms, float would lose them.
  double sum_sq = 0, sum_abs = 0;
  for (size_t p = 0; p < a.size(); p += 3) {
    double pixel_max = 0;
    for (size_t c = p; c < p + 3; ++c) {
      const double e = std::fabs(display_value(a[c], options.clamp) - display_value(b[c], options.clamp));
      // NaN must not hide: treat it as the worst error there is.
      const double err = std::isnan(e) ? std::numeric_limits<double>::infinity() : e;
      sum_sq += err * err;
      sum_abs += err;
      pixel_max = std::max(pixel_max, err);
    }
    d.max_abs = std::max(d.max_abs, pixel_max);
    if (pixel_max > options.tolerance) ++d.pixels_over;
  }
  const double n = static_cast<double>(a.size());
  d.rmse = std::sqrt(sum_sq / n);
  d.mean_abs = sum_abs / n;
  d.psnr = psnr_from_rmse(d.rmse);
  return d;
}

size_t count_non_finite(const std::vector<float>& rgb) {
  return static_cast<size_t>(
      std::count_if(rgb.begin(), rgb.end(), [](float v) { return !std::isfinite(v); }));
}

size_t count_black_pixels(const std::vector<float>& rgb) {
  size_t black = 0;
  for (size_t p = 0; p + 2 < rgb.size(); p += 3) {
    if (rgb[p] == 0 && rgb[p + 1] == 0 && rgb[p + 2] == 0) ++black;
  }
  return black;
}

}  // namespace rayfarm
