// Adaptive supersampling of one pixel (after Rayshade's contrast test).
// A pixel's samples form a k x k jittered grid (spp = k * k). Adaptive mode first
// traces a coarse subset -- the four corner cells of the grid -- and traces the
// other cells only if those four disagree by more than a contrast threshold.
// Unlike Rayshade, which compares a pixel with its neighbours, everything here
// depends on the pixel alone, so bands of rows stay independent; the price is
// that a feature falling between the four corners goes unseen.
#pragma once

#include <array>
#include <cassert>

#include "tracer/vec3.h"

namespace rayfarm {

// The cells traced first, as row-major indices into the k x k grid: the four
// corners for k >= 2 (distinct, ascending), the single cell for k == 1.
struct CoarseCells {
  std::array<int, 4> index{};
  int count = 0;
};
CoarseCells coarse_cells(int k);

// Rayshade's contrast: per channel (max - min) / (max + min) over the samples,
// largest over the channels; a channel whose max + min is ~0 contributes 0.
double max_contrast(const Vec3* samples, int count);

// Whether a pixel with these coarse samples must take its full k x k grid.
// A threshold <= 0 means uniform sampling: always refine.
bool needs_refinement(const Vec3* coarse, int count, double threshold);

// Largest number of cells handed to a batch shader at once: one Embree packet.
constexpr int kSampleBatch = 16;

// The cells a pixel traces first, ascending: the coarse cells when adaptive
// (threshold > 0, k >= 3); the whole grid when it is that small (k <= 2);
// none for a larger uniform grid, which finish_pixel() traces in batches of
// its own. A renderer may trace several pixels' first cells in one batch.
CoarseCells first_cells(int k, double threshold);

// The mean of `count` samples summed in order: a pixel's whole grid, in cell
// order, exactly as finish_pixel() sums it (a renderer that traces whole
// grids itself gets the same bits).
inline Vec3 grid_mean(const Vec3* samples, int count) {
  Vec3 sum;
  for (int i = 0; i < count; ++i) sum += samples[i];
  return sum / count;
}

// The cells of [c0, c1) that are not first cells, ascending, into out[];
// returns how many. first cells below c0 are coarse.index[0, next_coarse).
inline int other_cells(int c0, int c1, const CoarseCells& coarse, int next_coarse, int* out) {
  int count = 0;
  for (int c = c0; c < c1; ++c) {
    if (next_coarse < coarse.count && coarse.index[next_coarse] == c) {
      ++next_coarse;
    } else {
      out[count++] = c;
    }
  }
  return count;
}

// Adds cells [c0, c1) of a pixel's grid to `sum` in cell order: the first
// cells' values from first[next_coarse...] (next_coarse advances past them),
// the others' from rest[0...].
inline void add_cells(int c0, int c1, const CoarseCells& coarse, const Vec3* first, const Vec3* rest,
                      int& next_coarse, Vec3& sum) {
  for (int c = c0; c < c1; ++c) {
    if (next_coarse < coarse.count && coarse.index[next_coarse] == c) {
      sum += first[next_coarse++];
    } else {
      sum += *rest++;
    }
  }
}

// Estimates one pixel from a k x k grid, given its first_cells(k, threshold)
// as `coarse` and their values as `first` (unread when there are none). `shade(cells, count, rgb)`
// traces the `count` (<= kSampleBatch) listed row-major cells of the grid,
// ascending, and writes their RGB to rgb[0..count); a cell's value must not
// depend on which other cells are traced with it (sampler.h makes positions
// a pure function of the cell). A refined pixel sums all k*k samples in cell
// order, exactly as uniform sampling (threshold <= 0) does, so the two are
// bit-identical; an unrefined pixel averages its coarse samples. `traced`
// receives the number of samples taken, first cells included.
template <class ShadeBatch>
Vec3 finish_pixel(int k, double threshold, const CoarseCells& coarse, const Vec3* first, ShadeBatch&& shade,
                  int* traced = nullptr) {
  assert(k >= 1);
  const int n = k * k;
  if (coarse.count == n || (coarse.count > 0 && !needs_refinement(first, coarse.count, threshold))) {
    if (traced) *traced = coarse.count;
    return grid_mean(first, coarse.count);
  }
  // Full grid in windows of kSampleBatch cells; first cells reuse their value.
  Vec3 sum;
  int next_coarse = 0;
  std::array<int, kSampleBatch> cells;
  Vec3Scratch<kSampleBatch> rgb;
  for (int c0 = 0; c0 < n; c0 += kSampleBatch) {
    const int c1 = c0 + kSampleBatch < n ? c0 + kSampleBatch : n;
    const int count = other_cells(c0, c1, coarse, next_coarse, cells.data());
    if (count > 0) shade(cells.data(), count, rgb.data());
    add_cells(c0, c1, coarse, first, rgb.data(), next_coarse, sum);
  }
  if (traced) *traced = n;
  return sum / n;
}

// A refined pixel's mean from its first cells' values (`first`) and its
// other cells' values, ascending (`rest`, k * k - coarse.count of them),
// traced by the caller with other pixels' cells: finish_pixel()'s sum, in
// the same order, so the same bits.
inline Vec3 refined_mean(int k, const CoarseCells& coarse, const Vec3* first, const Vec3* rest) {
  Vec3 sum;
  int next_coarse = 0;
  add_cells(0, k * k, coarse, first, rest, next_coarse, sum);
  return sum / (k * k);
}

// The same for one pixel alone: its first cells, then finish_pixel().
template <class ShadeBatch>
Vec3 sample_pixel_batched(int k, double threshold, ShadeBatch&& shade, int* traced = nullptr) {
  const CoarseCells coarse = first_cells(k, threshold);
  Vec3Scratch<4> first;
  if (coarse.count > 0) shade(coarse.index.data(), coarse.count, first.data());
  return finish_pixel(k, threshold, coarse, first.data(), shade, traced);
}

// The same for a shader of one cell at a time: `shade(cell)` returns its RGB.
template <class Shade>
Vec3 sample_pixel(int k, double threshold, Shade&& shade, int* traced = nullptr) {
  return sample_pixel_batched(
      k, threshold,
      [&shade](const int* cells, int count, Vec3* rgb) {
        for (int i = 0; i < count; ++i) rgb[i] = shade(cells[i]);
      },
      traced);
}

}  // namespace rayfarm
