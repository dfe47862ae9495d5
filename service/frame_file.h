// The service's finished-frame format: "RFFRAME1", u32 width, u32 height
// (little-endian), then width * height * 3 IEEE floats, row-major, top row
// first -- the broker's assembled image as is. The service stores and serves
// frames this way so `rayfarm fetch` can write any format `render` can (PNG,
// EXR, ...) with the same bytes an in-process render writes.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "tracer/image_io.h"

namespace rayfarm {

std::string encode_frame(int width, int height, const std::vector<float>& rgb);
// Throws InputError "NAME: ..." for anything but a whole, well-formed frame.
RgbImage decode_frame(std::string_view bytes, const std::string& name);

}  // namespace rayfarm
