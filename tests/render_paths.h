// What the renderer tests share: the sample counts that take every path of
// the renderer, and byte equality of two renders.
#pragma once

#include <cstring>
#include <vector>

namespace rayfarm::test {

struct Sampling {
  int spp;
  double adaptive_contrast;
};

// One sample (the pixel centre), whole grids traced in tiles (16, 64), a grid
// too large to trace whole (81, in the refined pixels' tiles), and adaptive.
inline constexpr Sampling kEveryRenderPath[] = {{1, 0}, {16, 0}, {64, 0}, {81, 0}, {16, 0.1}};

inline bool same_bytes(const std::vector<float>& a, const std::vector<float>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0;
}

}  // namespace rayfarm::test
