// The OpenImageIO side of image_io.h, built as the module librayfarm_imageio.so
// (interface in image_io_module.h). Every entry point catches everything and
// reports it as a status plus message, so no exception unwinds into the loader.
// The 8-bit conversion is the caller's (to_8bit) so its rounding is ours and
// stays stable across OpenImageIO versions.
#include <OpenImageIO/imageio.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <memory>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include "tracer/oiio/image_io_module.h"

#define RAYFARM_EXPORT extern "C" __attribute__((visibility("default")))

namespace rayfarm::image_module {
namespace {

// Bad input (unknown format, unreadable or unwritable file): InputError on the
// caller's side.
struct BadInput : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// Formats that store our linear floats as they are.
bool stores_float(const std::string& format_name) {
  return format_name == "openexr" || format_name == "hdr";
}

std::string one_line(const std::string& message) {
  // OpenImageIO messages can span lines; keep ours on one.
  std::string out;
  for (char c : message) out += c == '\n' ? ' ' : c;
  while (!out.empty() && out.back() == ' ') out.pop_back();
  return out;
}

// "path: cannot write image: OpenImageIO's message (system error)". Its
// TIFF and JPEG writers say only 'Could not open "path"', its EXR writer
// "File output failed", hiding a full disk or too many open files; the
// errno of the failed call is still set (cleared before each call).
[[noreturn]] void fail_write(const std::string& path, const std::string& message, int error) {
  std::string what = path + ": cannot write image: " + one_line(message);
  const std::string cause = error ? std::strerror(error) : "";
  if (!cause.empty() && what.find(cause) == std::string::npos) what += " (" + cause + ")";
  throw BadInput(what);
}

std::unique_ptr<OIIO::ImageOutput> create_output(const std::string& path) {
  auto out = OIIO::ImageOutput::create(path);
  if (!out)
    throw BadInput(path + ": unknown image format (use .png, .tif, .exr, ...): " + one_line(OIIO::geterror()));
  return out;
}

void write(const std::string& path, int width, int height, const float* rgb, Quantise quantise) {
  auto out = create_output(path);
  const bool as_float = stores_float(out->format_name());
  const OIIO::TypeDesc type = as_float ? OIIO::TypeDesc::FLOAT : OIIO::TypeDesc::UINT8;
  OIIO::ImageSpec spec(width, height, 3, type);
  // TIFF and EXR writers stamp the current time unless told otherwise; an
  // empty DateTime keeps equal renders byte-equal on disk.
  spec.attribute("DateTime", "");
  errno = 0;
  if (!out->open(path, spec)) {
    const int error = errno;
    fail_write(path, out->geterror(), error);
  }
  bool ok = false;
  errno = 0;
  if (as_float) {
    ok = out->write_image(OIIO::TypeDesc::FLOAT, rgb);
  } else {
    std::vector<uint8_t> bytes(static_cast<size_t>(width) * height * 3);
    for (size_t i = 0; i < bytes.size(); ++i) bytes[i] = quantise(rgb[i]);
    ok = out->write_image(OIIO::TypeDesc::UINT8, bytes.data());
  }
  int error = errno;  // the failed write's, if it failed; else the close's
  if (ok) errno = 0;
  if (!out->close() || !ok) {
    if (ok) error = errno;
    fail_write(path, out->geterror(), error);
  }
}

void read(const std::string& path, ReserveRgb reserve, void* image) {
  auto in = OIIO::ImageInput::open(path);
  if (!in) throw BadInput(path + ": cannot read image: " + one_line(OIIO::geterror()));
  const OIIO::ImageSpec& spec = in->spec();
  const int channels = spec.nchannels;
  const size_t pixels = static_cast<size_t>(spec.width) * spec.height;
  std::vector<float> all(pixels * channels);
  if (!in->read_image(0, 0, 0, channels, OIIO::TypeDesc::FLOAT, all.data()))
    throw BadInput(path + ": cannot read image: " + one_line(in->geterror()));
  float* rgb = reserve(image, spec.width, spec.height);
  if (!rgb) throw std::runtime_error(path + ": out of memory for a " + std::to_string(spec.width) + "x" +
                                     std::to_string(spec.height) + " image");
  // Grey images are replicated, alpha and further channels dropped.
  for (size_t p = 0; p < pixels; ++p)
    for (int c = 0; c < 3; ++c) rgb[3 * p + c] = all[channels * p + (channels >= 3 ? c : 0)];
}

// Runs `body`, turning whatever it throws into a status and message.
template <typename Body>
int guarded(char* error, size_t error_size, Body body) noexcept {
  auto fail = [&](Status status, const char* message) {
    if (error && error_size > 0) std::snprintf(error, error_size, "%s", message);
    return status;
  };
  try {
    body();
    return kOk;
  } catch (const BadInput& e) {
    return fail(kBadInput, e.what());
  } catch (const std::exception& e) {
    return fail(kInternal, e.what());
  } catch (...) {
    return fail(kInternal, "unknown error in the OpenImageIO module");
  }
}

}  // namespace
}  // namespace rayfarm::image_module

using namespace rayfarm::image_module;

RAYFARM_EXPORT int rayfarm_imageio_abi_version() { return kAbiVersion; }

RAYFARM_EXPORT int rayfarm_imageio_check(const char* path, char* error, size_t error_size) {
  return guarded(error, error_size, [&] { create_output(path); });
}

RAYFARM_EXPORT int rayfarm_imageio_write(const char* path, int width, int height, const float* rgb,
                                         Quantise quantise, char* error, size_t error_size) {
  return guarded(error, error_size, [&] { write(path, width, height, rgb, quantise); });
}

RAYFARM_EXPORT int rayfarm_imageio_read(const char* path, ReserveRgb reserve, void* image, char* error,
                                        size_t error_size) {
  return guarded(error, error_size, [&] { read(path, reserve, image); });
}

// The loader casts dlsym results to these types; keep them in step.
static_assert(std::is_same_v<decltype(&rayfarm_imageio_abi_version), AbiVersionFn>);
static_assert(std::is_same_v<decltype(&rayfarm_imageio_check), CheckFn>);
static_assert(std::is_same_v<decltype(&rayfarm_imageio_write), WriteFn>);
static_assert(std::is_same_v<decltype(&rayfarm_imageio_read), ReadFn>);
