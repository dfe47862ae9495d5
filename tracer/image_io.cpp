// OpenImageIO glue for image_io.h. The 8-bit conversion is done here rather
// than by OpenImageIO so its rounding is ours and stays stable across versions.
#include "tracer/image_io.h"

#include <OpenImageIO/imageio.h>

#include <cmath>
#include <memory>
#include <stdexcept>

#include "tracer/error.h"

namespace rayfarm {
namespace {

// Formats that store our linear floats as they are.
bool stores_float(const std::string& format_name) {
  return format_name == "openexr" || format_name == "hdr";
}

std::string oiio_error(const std::string& message) {
  // OpenImageIO messages can span lines; keep ours on one.
  std::string out;
  for (char c : message) out += c == '\n' ? ' ' : c;
  while (!out.empty() && out.back() == ' ') out.pop_back();
  return out;
}

std::unique_ptr<OIIO::ImageOutput> create_output(const std::string& path) {
  auto out = OIIO::ImageOutput::create(path);
  if (!out)
    throw InputError(path + ": unknown image format (use .png, .tif, .exr, ...): " +
                     oiio_error(OIIO::geterror()));
  return out;
}

}  // namespace

void check_image_path(const std::string& path) { create_output(path); }

uint8_t to_8bit(float value) {
  if (!(value > 0)) return 0;  // also NaN
  if (value >= 1) return 255;
  return static_cast<uint8_t>(std::floor(value * 255.0f + 0.5f));
}

void write_image(const std::string& path, int width, int height, const std::vector<float>& rgb) {
  if (width <= 0 || height <= 0 || rgb.size() != static_cast<size_t>(width) * height * 3)
    throw std::invalid_argument("write_image: rgb does not hold width * height * 3 values");
  auto out = create_output(path);
  const bool as_float = stores_float(out->format_name());
  const OIIO::TypeDesc type = as_float ? OIIO::TypeDesc::FLOAT : OIIO::TypeDesc::UINT8;
  OIIO::ImageSpec spec(width, height, 3, type);
  // TIFF and EXR writers stamp the current time unless told otherwise; an
  // empty DateTime keeps equal renders byte-equal on disk.
  spec.attribute("DateTime", "");
  if (!out->open(path, spec)) throw InputError(path + ": cannot write image: " + oiio_error(out->geterror()));
  bool ok = false;
  if (as_float) {
    ok = out->write_image(OIIO::TypeDesc::FLOAT, rgb.data());
  } else {
    std::vector<uint8_t> bytes(rgb.size());
    for (size_t i = 0; i < rgb.size(); ++i) bytes[i] = to_8bit(rgb[i]);
    ok = out->write_image(OIIO::TypeDesc::UINT8, bytes.data());
  }
  if (!out->close() || !ok)
    throw InputError(path + ": cannot write image: " + oiio_error(out->geterror()));
}

RgbImage read_image(const std::string& path) {
  auto in = OIIO::ImageInput::open(path);
  if (!in) throw InputError(path + ": cannot read image: " + oiio_error(OIIO::geterror()));
  const OIIO::ImageSpec& spec = in->spec();
  const int channels = spec.nchannels;
  std::vector<float> all(static_cast<size_t>(spec.width) * spec.height * channels);
  if (!in->read_image(0, 0, 0, channels, OIIO::TypeDesc::FLOAT, all.data()))
    throw InputError(path + ": cannot read image: " + oiio_error(in->geterror()));
  RgbImage image;
  image.width = spec.width;
  image.height = spec.height;
  image.rgb.resize(static_cast<size_t>(spec.width) * spec.height * 3);
  const size_t pixels = static_cast<size_t>(spec.width) * spec.height;
  for (size_t p = 0; p < pixels; ++p)
    for (int c = 0; c < 3; ++c) image.rgb[3 * p + c] = all[channels * p + (channels >= 3 ? c : 0)];
  return image;
}

}  // namespace rayfarm
