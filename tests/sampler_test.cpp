// Where a pixel's samples fall (tracer/sampler.h): each in its own cell of
// the k x k grid, in k * k different fine columns and rows (n-rooks), and a
// pure function of the pixel and the cell.
#include <doctest/doctest.h>

#include <cmath>
#include <set>
#include <utility>
#include <vector>

#include "tracer/sampler.h"

using namespace rayfarm;

namespace {

std::vector<PixelSample> samples_of(uint64_t key, int k) {
  const PixelGrid grid(key, k);
  std::vector<PixelSample> out;
  for (int c = 0; c < k * k; ++c) out.push_back(grid.sample(c));
  return out;
}

// The fine column (or row) of the k^2 x k^2 grid that coordinate v falls in.
int fine(double v, int k) { return static_cast<int>(std::floor(v * k * k)); }

}  // namespace

TEST_CASE("sampler: every sample lies in its own cell, and in a fine column and row no other sample takes") {
  for (const int k : {2, 3, 4, 7, 8, 16, 32}) {
    for (int x = 0; x < 20; ++x) {
      CAPTURE(k);
      CAPTURE(x);
      const std::vector<PixelSample> samples = samples_of(pixel_key(1, x, 3 * x + 1), k);
      std::set<int> columns, rows;
      int outside = 0;
      for (int c = 0; c < k * k; ++c) {
        const PixelSample& p = samples[c];
        outside += !(p.x >= double(c % k) / k && p.x < double(c % k + 1) / k);
        outside += !(p.y >= double(c / k) / k && p.y < double(c / k + 1) / k);
        columns.insert(fine(p.x, k));
        rows.insert(fine(p.y, k));
      }
      CHECK(outside == 0);
      CHECK(columns.size() == size_t(k * k));
      CHECK(rows.size() == size_t(k * k));
    }
  }
}

TEST_CASE("sampler: a sample depends only on the pixel's key and its cell") {
  const int k = 4;
  const PixelGrid a(pixel_key(7, 10, 20), k), b(pixel_key(7, 10, 20), k);
  const PixelGrid other_pixel(pixel_key(7, 11, 20), k), other_seed(pixel_key(8, 10, 20), k);
  int moved_pixel = 0, moved_seed = 0;
  for (int c = k * k - 1; c >= 0; --c) {  // in any order
    CHECK(a.sample(c).x == b.sample(c).x);
    CHECK(a.sample(c).y == b.sample(c).y);
    moved_pixel += a.sample(c).x != other_pixel.sample(c).x;
    moved_seed += a.sample(c).x != other_seed.sample(c).x;
  }
  CHECK(moved_pixel > k * k / 2);
  CHECK(moved_seed > k * k / 2);
}

TEST_CASE("sampler: one sample a pixel is its centre, the shuffles differ from pixel to pixel") {
  const PixelSample centre = PixelGrid(pixel_key(1, 5, 5), 1).sample(0);
  CHECK(centre.x == 0.5);
  CHECK(centre.y == 0.5);
  // The fine column each cell row's samples take inside their cells: a
  // shuffle of 0..k-1 per pixel, so 100 pixels show many different ones.
  const int k = 4;
  std::set<std::vector<int>> shuffles;
  for (int x = 0; x < 100; ++x) {
    const std::vector<PixelSample> samples = samples_of(pixel_key(1, x, 0), k);
    std::vector<int> columns;
    for (int row = 0; row < k; ++row) columns.push_back(fine(samples[row * k].x, k) % k);
    shuffles.insert(columns);
  }
  CHECK(shuffles.size() > 15);  // of 24 possible
}
