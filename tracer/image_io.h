// Image files, the format chosen by the file extension: PNG through libpng,
// everything else through OpenImageIO.
// EXR (and HDR) keep the linear float RGB as 32-bit floats; every other format
// (png, tif, ppm, ...) gets 8 bits per channel: clamped to [0, 1], no gamma
// (classic SPD renders are linear), rounded to nearest -- a deterministic
// conversion, so equal renders give byte-equal files. OpenImageIO lives in a
// module loaded on the first non-PNG call (see tracer/oiio/image_io_module.h);
// if it cannot be loaded, these functions throw std::runtime_error naming the
// paths tried.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace rayfarm {

// Float RGB, row-major, top row first, width * height * 3 values.
struct RgbImage {
  int width = 0;
  int height = 0;
  std::vector<float> rgb;
};

// The 8-bit value written for a linear channel value: round(clamp(v, 0, 1) * 255),
// NaN as 0.
uint8_t to_8bit(float value);
// `count` values at once.
void to_8bit(const float* values, size_t count, uint8_t* bytes);

// Throws the InputError write_image would for an extension OpenImageIO cannot
// write, so a long render can fail fast.
void check_image_path(const std::string& path);

// Writes `rgb` (width * height * 3 floats). Throws InputError naming the path
// for an unknown extension or a file that cannot be written.
void write_image(const std::string& path, int width, int height, const std::vector<float>& rgb);

// Reads any image OpenImageIO knows as float RGB (8-bit values become v / 255;
// grey images are replicated, alpha is dropped). Throws InputError.
RgbImage read_image(const std::string& path);

}  // namespace rayfarm
