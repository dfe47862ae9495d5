// Finished-frame bytes; see frame_file.h.
#include "service/frame_file.h"

#include <cstring>

#include "service/little_endian.h"
#include "tracer/error.h"

namespace rayfarm {
namespace {

constexpr char kMagic[8] = {'R', 'F', 'F', 'R', 'A', 'M', 'E', '1'};
constexpr size_t kHeader = 16;
constexpr uint32_t kMaxSide = 65536;

}  // namespace

// Floats are copied in host order: rayfarm runs on little-endian machines only
// (as the protocol's pixel payload assumes, protocol/SPEC.md).
std::string encode_frame(int width, int height, const std::vector<float>& rgb) {
  std::string out(kMagic, sizeof kMagic);
  put_u32(out, static_cast<uint32_t>(width));
  put_u32(out, static_cast<uint32_t>(height));
  out.append(reinterpret_cast<const char*>(rgb.data()), rgb.size() * sizeof(float));
  return out;
}

RgbImage decode_frame(std::string_view bytes, const std::string& name) {
  if (bytes.size() < kHeader || std::memcmp(bytes.data(), kMagic, sizeof kMagic) != 0)
    throw InputError(name + ": not a rayfarm frame (bad header)");
  RgbImage img;
  const uint32_t w = get_u32(bytes, 8), h = get_u32(bytes, 12);
  if (w < 1 || h < 1 || w > kMaxSide || h > kMaxSide)
    throw InputError(name + ": frame size " + std::to_string(w) + "x" + std::to_string(h) + " out of range");
  const size_t floats = size_t{w} * h * 3;
  if (bytes.size() != kHeader + floats * sizeof(float))
    throw InputError(name + ": frame of " + std::to_string(w) + "x" + std::to_string(h) + " needs " +
                     std::to_string(kHeader + floats * sizeof(float)) + " bytes, found " + std::to_string(bytes.size()));
  img.width = static_cast<int>(w);
  img.height = static_cast<int>(h);
  img.rgb.resize(floats);
  std::memcpy(img.rgb.data(), bytes.data() + kHeader, floats * sizeof(float));
  return img;
}

}  // namespace rayfarm
