// The pixels an eye ray can meet the scene through (screen_footprint.h).
#include "tracer/screen_footprint.h"

#include <algorithm>
#include <array>
#include <cmath>

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

}  // namespace

ScreenFootprint::ScreenFootprint(int width, int height) : rows_(height, Span{0, width}), width_(width) {}

ScreenFootprint::ScreenFootprint(const CameraModel& camera, int width, int height, const Vec3& lo,
                                 const Vec3& hi)
    : ScreenFootprint(width, height) {
  if (!(lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z)) return;
  std::array<Vec3, 8> box;
  for (int c = 0; c < 8; ++c) box[c] = {c & 1 ? hi.x : lo.x, c & 2 ? hi.y : lo.y, c & 4 ? hi.z : lo.z};
  // Wholly behind the eye (or level with it): every eye ray goes forward
  // from the eye, so none meets it.
  if (std::all_of(box.begin(), box.end(), [&](const Vec3& p) { return dot(p, camera.forward()) <= 0; })) {
    for (Span& row : rows_) row = {0, 0};
    return;
  }
  std::array<Point2, 8> corners;
  for (int c = 0; c < 8; ++c) {
    const Vec3& p = box[c];
    // Behind the eye, or so near its plane that the image positions lose
    // their precision: nothing ruled out.
    if (!camera.project(p, corners[c].x, corners[c].y)) return;
    if (!(std::fabs(corners[c].x) < kFarPixels && std::fabs(corners[c].y) < kFarPixels)) return;
  }
  const double m = kMarginPixels;
  for (int y = 0; y < height; ++y) {
    // Pixel x's square [x, x + 1] x [y, y + 1], grown by m, meets the hull
    // iff x + 1 + m >= x_min and x - m <= x_max, its rows meeting it too.
    double x_min, x_max;
    Span& row = rows_[y];
    if (!hull_span_in_band(corners, y - m, y + 1 + m, x_min, x_max)) {
      row = {0, 0};
      continue;
    }
    const double first = std::ceil(x_min - 1 - m), last = std::floor(x_max + m);  // may be far outside
    row.begin = static_cast<int>(std::clamp(first, 0.0, static_cast<double>(width)));
    row.end = static_cast<int>(std::clamp(last + 1, 0.0, static_cast<double>(width)));
    if (row.end < row.begin) row.end = row.begin;
  }
}

bool ScreenFootprint::any(int x0, int x1, int y0, int y1) const {
  const int height = static_cast<int>(rows_.size());
  for (int y = std::max(0, y0); y <= std::min(height - 1, y1); ++y) {
    const Span& row = rows_[y];
    if (row.begin < row.end && row.begin <= x1 && row.end > x0) return true;
  }
  return false;
}

long ScreenFootprint::ruled_out() const {
  long n = 0;
  for (const Span& row : rows_) n += width_ - (row.end - row.begin);
  return n;
}

}  // namespace rayfarm
