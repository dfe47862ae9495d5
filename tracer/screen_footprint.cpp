// The pixels an eye ray can meet the scene through (screen_footprint.h).
#include "tracer/screen_footprint.h"

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <cstdint>

#include "tracer/box.h"

namespace rayfarm {
namespace {

struct Point2 {
  double x, y;
};

// Corner images farther out than this many pixels rule nothing out, so the
// arithmetic below stays far from overflow.
constexpr double kFarPixels = 1e9;

// The x-extent of the convex hull of `points` where it crosses the band
// lo <= y <= hi: the extremes of the points inside the band and of the
// segments between any two of them where they cross its edges (the hull's
// edges are among those segments, and the others lie inside it). False
// when the hull misses the band.
bool hull_span_in_band(const std::array<Point2, 8>& points, double lo, double hi, double& x_min, double& x_max) {
  x_min = HUGE_VAL, x_max = -HUGE_VAL;
  const auto take = [&](double x) { x_min = std::min(x_min, x), x_max = std::max(x_max, x); };
  for (size_t a = 0; a < points.size(); ++a) {
    const Point2& p = points[a];
    if (p.y >= lo && p.y <= hi) take(p.x);
    for (size_t b = a + 1; b < points.size(); ++b) {
      const Point2& q = points[b];
      for (const double edge : {lo, hi}) {
        if ((p.y - edge) * (q.y - edge) >= 0) continue;  // both on one side (or an end on it: taken above)
        take(p.x + (q.x - p.x) * ((edge - p.y) / (q.y - p.y)));
      }
    }
  }
  return x_min <= x_max;
}

// Wholly behind the eye (or level with it): every eye ray goes forward from
// the eye, so none meets the hull of points[0, count).
bool behind_eye(const CameraModel& camera, const Vec3* points, int count) {
  return std::all_of(points, points + count, [&](const Vec3& p) { return dot(p, camera.forward()) <= 0; });
}

// The 64-bit words of a row that cells x0 <= x <= x1 fall in (a cell a
// bit), and the bits of the first and the last word that are theirs.
struct RowWords {
  int first, last;
  uint64_t first_bits, last_bits;
  RowWords(int x0, int x1)
      : first(x0 >> 6),
        last(x1 >> 6),
        first_bits(~uint64_t{0} << (x0 & 63)),
        last_bits(~uint64_t{0} >> (63 - (x1 & 63))) {
    if (first == last) first_bits = last_bits = first_bits & last_bits;
  }
};

// The image of p; false when p lies behind the eye, or so near its plane or
// so far out that the image position loses its precision.
bool project(const CameraModel& camera, const Vec3& p, Point2& out) {
  return camera.project(p, out.x, out.y) && std::fabs(out.x) < kFarPixels && std::fabs(out.y) < kFarPixels;
}

// Cells of 2^shift pixels along a side of `pixels`, the last maybe cut short.
long long cells_along(int pixels, int shift) {
  return (static_cast<long long>(std::max(pixels, 0)) + (1LL << shift) - 1) >> shift;
}

// The smallest shift whose cells of 2^shift x 2^shift pixels number at
// most kMaxCells.
int cell_shift(int width, int height) {
  int shift = 0;
  while (cells_along(width, shift) * cells_along(height, shift) > ScreenFootprint::kMaxCells) ++shift;
  return shift;
}

}  // namespace

ScreenFootprint::ScreenFootprint(int width, int height)
    : width_(width),
      height_(height),
      shift_(cell_shift(width, height)),
      cells_wide_(static_cast<int>(cells_along(width, shift_))),
      cells_high_(static_cast<int>(cells_along(height, shift_))),
      words_((size_t(cells_wide_) + 63) / 64) {
  bits_.assign(words_ * cells_high_, 0);
  keep_all();
}

ScreenFootprint ScreenFootprint::none(int width, int height) {
  ScreenFootprint f(width, height);
  std::fill(f.bits_.begin(), f.bits_.end(), 0);
  return f;
}

ScreenFootprint::ScreenFootprint(const CameraModel& camera, int width, int height, const Vec3& lo,
                                 const Vec3& hi)
    : ScreenFootprint(width, height) {
  if (!(lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z)) return;
  const std::array<Vec3, 8> box = box_corners({lo, hi});
  if (behind_eye(camera, box.data(), static_cast<int>(box.size()))) {
    std::fill(bits_.begin(), bits_.end(), 0);
    return;
  }
  std::array<Point2, 8> corners;
  for (int c = 0; c < 8; ++c) {
    if (!project(camera, box[c], corners[c])) return;
  }
  std::fill(bits_.begin(), bits_.end(), 0);
  const double m = kMarginPixels;
  for (int y = 0; y < height; ++y) {
    // Pixel x's square [x, x + 1] x [y, y + 1], grown by m, meets the hull
    // iff x + 1 + m >= x_min and x - m <= x_max, its rows meeting it too.
    double x_min, x_max;
    if (hull_span_in_band(corners, y - m, y + 1 + m, x_min, x_max)) keep(x_min - 1 - m, x_max + m, y, y);
  }
}

void ScreenFootprint::add_hull(const CameraModel& camera, const Vec3* points, int count) {
  if (unbounded_ || count <= 0 || behind_eye(camera, points, count)) return;
  double x_min = HUGE_VAL, x_max = -HUGE_VAL, y_min = HUGE_VAL, y_max = -HUGE_VAL;
  for (int i = 0; i < count; ++i) {
    Point2 p;
    if (!project(camera, points[i], p)) {
      unbounded_ = true;
      keep_all();
      return;
    }
    x_min = std::min(x_min, p.x), x_max = std::max(x_max, p.x);
    y_min = std::min(y_min, p.y), y_max = std::max(y_max, p.y);
  }
  // Pixel (x, y)'s square grown by m meets the rectangle around the images
  // iff x + 1 + m >= x_min and x - m <= x_max, and likewise for y.
  const double m = kMarginPixels;
  keep(x_min - 1 - m, x_max + m, y_min - 1 - m, y_max + m);
}

void ScreenFootprint::keep_only(const ScreenFootprint& other) {
  assert(other.bits_.size() == bits_.size());  // the same image
  for (size_t w = 0; w < bits_.size(); ++w) bits_[w] &= other.bits_[w];
}

bool ScreenFootprint::keeps_all_of(const ScreenFootprint& other) const {
  assert(other.bits_.size() == bits_.size());
  for (size_t w = 0; w < bits_.size(); ++w) {
    if (other.bits_[w] & ~bits_[w]) return false;
  }
  return true;
}

void ScreenFootprint::keep(double x0, double x1, double y0, double y1) {
  // Pixels x with x >= x0 and x <= x1; the bounds may be far outside the image.
  const auto first = [](double v, int size) { return static_cast<int>(std::clamp(std::ceil(v), 0.0, double(size))); };
  const auto last = [](double v, int size) {
    return static_cast<int>(std::clamp(std::floor(v), -1.0, double(size - 1)));
  };
  const int xa = first(x0, width_), xb = last(x1, width_), ya = first(y0, height_), yb = last(y1, height_);
  if (xa > xb || ya > yb) return;
  for (int cy = ya >> shift_; cy <= yb >> shift_; ++cy) keep_cells(cy, xa >> shift_, xb >> shift_);
}

void ScreenFootprint::keep_cells(int cy, int cx0, int cx1) {
  uint64_t* row = &bits_[row_word(cy)];
  const RowWords words(cx0, cx1);
  for (int w = words.first + 1; w < words.last; ++w) row[w] = ~uint64_t{0};
  row[words.first] |= words.first_bits;
  row[words.last] |= words.last_bits;
}

void ScreenFootprint::keep_all() {
  if (cells_wide_ > 0) {
    for (int cy = 0; cy < cells_high_; ++cy) keep_cells(cy, 0, cells_wide_ - 1);
  }
}

bool ScreenFootprint::any(int x0, int x1, int y0, int y1) const {
  x0 = std::max(0, x0), x1 = std::min(width_ - 1, x1);
  y0 = std::max(0, y0), y1 = std::min(height_ - 1, y1);
  if (x0 > x1 || y0 > y1) return false;
  const RowWords words(x0 >> shift_, x1 >> shift_);
  for (int cy = y0 >> shift_; cy <= y1 >> shift_; ++cy) {
    const uint64_t* row = &bits_[row_word(cy)];
    if ((row[words.first] & words.first_bits) || (row[words.last] & words.last_bits)) return true;
    for (int w = words.first + 1; w < words.last; ++w) {
      if (row[w]) return true;
    }
  }
  return false;
}

long ScreenFootprint::ruled_out() const {
  // The image's last column of cells may be narrower than the others.
  const long last_cell_width = width_ - (long(cells_wide_ - 1) << shift_);
  long kept = 0;
  for (int cy = 0; cy < cells_high_; ++cy) {
    const uint64_t* row = &bits_[row_word(cy)];
    long cells = 0;
    for (size_t w = 0; w < words_; ++w) cells += __builtin_popcountll(row[w]);
    const bool last_kept = cells_wide_ > 0 && ((row[(cells_wide_ - 1) >> 6] >> ((cells_wide_ - 1) & 63)) & 1);
    const long pixels = (cells << shift_) - (last_kept ? (1L << shift_) - last_cell_width : 0);
    const long rows = std::min(height_, (cy + 1) << shift_) - (cy << shift_);
    kept += pixels * rows;
  }
  return long(width_) * height_ - kept;
}

}  // namespace rayfarm
