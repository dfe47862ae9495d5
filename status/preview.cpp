// Nearest-done-row fill; see preview.h.
#include "status/preview.h"

#include <algorithm>
#include <cassert>
#include <cstdlib>
#include <cstring>

#include "tracer/image_io.h"
#include "tracer/png_file.h"

namespace rayfarm {

// Two sweeps: the nearest done row above each row, then below; the closer wins.
std::vector<int> preview_source_rows(const std::vector<bool>& done) {
  const int height = static_cast<int>(done.size());
  std::vector<int> above(done.size(), -1), source(done.size(), -1);
  for (int y = 0, last = -1; y < height; ++y) {
    if (done[static_cast<size_t>(y)]) last = y;
    above[static_cast<size_t>(y)] = last;
  }
  for (int y = height - 1, below = -1; y >= 0; --y) {
    if (done[static_cast<size_t>(y)]) below = y;
    const int up = above[static_cast<size_t>(y)];
    if (up < 0) source[static_cast<size_t>(y)] = below;
    else if (below < 0) source[static_cast<size_t>(y)] = up;
    else source[static_cast<size_t>(y)] = y - up <= below - y ? up : below;
  }
  return source;
}

int preview_fill_distance(const std::vector<bool>& done) {
  const std::vector<int> source = preview_source_rows(done);
  int worst = 0;
  for (size_t y = 0; y < source.size(); ++y) {
    if (source[y] < 0) return static_cast<int>(done.size());
    worst = std::max(worst, std::abs(static_cast<int>(y) - source[y]));
  }
  return worst;
}

std::vector<uint8_t> preview_rgb8(int width, int height, const std::vector<float>& rgb,
                                  const std::vector<bool>& done) {
  assert(static_cast<int>(done.size()) == height);
  assert(rgb.size() == static_cast<size_t>(width) * height * 3);
  const size_t stride = static_cast<size_t>(width) * 3;
  std::vector<uint8_t> out(stride * static_cast<size_t>(height), 0);
  const std::vector<int> source = preview_source_rows(done);
  // Convert each done row once; the filled rows copy their source's bytes.
  for (int y = 0; y < height; ++y) {
    if (!done[static_cast<size_t>(y)]) continue;
    for (size_t i = 0; i < stride; ++i) out[stride * y + i] = to_8bit(rgb[stride * y + i]);
  }
  for (int y = 0; y < height; ++y) {
    const int s = source[static_cast<size_t>(y)];
    if (s >= 0 && s != y) std::memcpy(&out[stride * y], &out[stride * s], stride);
  }
  return out;
}

std::string preview_png(int width, int height, const std::vector<float>& rgb, const std::vector<bool>& done) {
  return encode_png(width, height, preview_rgb8(width, height, rgb, done).data(), "preview");
}

}  // namespace rayfarm
