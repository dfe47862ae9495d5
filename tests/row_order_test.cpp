// Coarse-to-fine row order (broker/row_order.h): a permutation, coarse levels
// first, and a cursor that hands every row out exactly once for any task sizes.
#include <doctest/doctest.h>

#include <algorithm>
#include <random>
#include <vector>

#include "broker/row_order.h"

using namespace rayfarm;

namespace {

bool is_permutation_of_range(std::vector<int> v, int count) {
  std::sort(v.begin(), v.end());
  for (int i = 0; i < count; ++i)
    if (v[static_cast<size_t>(i)] != i) return false;
  return static_cast<int>(v.size()) == count;
}

// The largest distance from any row to the nearest of `done`.
int max_distance_to_done(const std::vector<int>& done, int height) {
  std::vector<char> is_done(static_cast<size_t>(height), 0);
  for (int y : done) is_done[static_cast<size_t>(y)] = 1;
  int worst = 0;
  for (int y = 0; y < height; ++y) {
    int d = 0;
    while (!(y - d >= 0 && is_done[static_cast<size_t>(y - d)]) && !(y + d < height && is_done[static_cast<size_t>(y + d)])) ++d;
    worst = std::max(worst, d);
  }
  return worst;
}

}  // namespace

TEST_CASE("row order: the grid of every 8th row in bit-reversed order, then the rest top to bottom") {
  CHECK(coarse_to_fine(8, 1) == std::vector<int>{0, 4, 2, 6, 1, 5, 3, 7});
  CHECK(coarse_to_fine(5, 1) == std::vector<int>{0, 4, 2, 1, 3});
  CHECK(coarse_to_fine(20) == std::vector<int>{0, 16, 8, 1, 2, 3, 4, 5, 6, 7, 9, 10, 11, 12, 13, 14, 15, 17, 18, 19});
  CHECK(coarse_to_fine(1) == std::vector<int>{0});
  CHECK(coarse_to_fine(0).empty());
  for (int n : {2, 3, 7, 100, 480, 512, 1080}) {
    CHECK(is_permutation_of_range(coarse_to_fine(n), n));
    CHECK(is_permutation_of_range(coarse_to_fine(n, 1), n));
  }
  // The last eighth of the order is the frame's bottom rows, as top to bottom would end.
  const std::vector<int> order = coarse_to_fine(512);
  CHECK(std::is_sorted(order.begin() + 64, order.end()));
  CHECK(order.back() == 511);
}

TEST_CASE("row order: the first 1/32 of the rows are every 32nd row, then every 16th") {
  const std::vector<int> order = coarse_to_fine(512);
  std::vector<int> first(order.begin(), order.begin() + 16);
  std::sort(first.begin(), first.end());
  for (int i = 0; i < 16; ++i) CHECK(first[static_cast<size_t>(i)] == 32 * i);
  std::vector<int> second(order.begin(), order.begin() + 32);
  std::sort(second.begin(), second.end());
  for (int i = 0; i < 32; ++i) CHECK(second[static_cast<size_t>(i)] == 16 * i);
}

TEST_CASE("row order: the first 10% covers the frame (every row within 16 of a done row)") {
  for (int height : {480, 512, 1080}) {
    const std::vector<int> order = coarse_to_fine(height);
    const std::vector<int> tenth(order.begin(), order.begin() + height / 10);
    CAPTURE(height);
    CHECK(max_distance_to_done(tenth, height) < 16);
    // Top to bottom, the same rows would leave the bottom 90% uncovered.
    std::vector<int> top(static_cast<size_t>(height / 10));
    for (size_t i = 0; i < top.size(); ++i) top[i] = static_cast<int>(i);
    CHECK(max_distance_to_done(top, height) > height / 2);
  }
}

TEST_CASE("row order: the cursor hands out bands in the same order of band index") {
  RowCursor cursor(160);
  std::vector<int> starts;
  while (auto band = cursor.take(10)) {
    CHECK(band->second - band->first == 10);
    starts.push_back(band->first);
  }
  CHECK(starts == std::vector<int>{0, 80, 10, 20, 30, 40, 50, 60, 70, 90, 100, 110, 120, 130, 140, 150});
  CHECK(cursor.remaining() == 0);
}

TEST_CASE("row order: mixed task sizes still hand out every row exactly once, in contiguous bands") {
  std::mt19937 rng(7);
  for (int height : {1, 17, 100, 512}) {
    RowCursor cursor(height);
    std::vector<int> count(static_cast<size_t>(height), 0);
    int tasks = 0;
    while (true) {
      const int rows = 1 + static_cast<int>(rng() % 12);
      const auto band = cursor.take(rows);
      if (!band) break;
      ++tasks;
      REQUIRE(band->first < band->second);
      CHECK(band->second - band->first <= rows);
      for (int y = band->first; y < band->second; ++y) ++count[static_cast<size_t>(y)];
    }
    CAPTURE(height);
    CHECK(cursor.remaining() == 0);
    CHECK(std::all_of(count.begin(), count.end(), [](int c) { return c == 1; }));
    CHECK(tasks <= height);
  }
}
