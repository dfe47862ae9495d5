// image_io.h: PNG through libpng (png_file.h), every other format through the
// OpenImageIO module (tracer/oiio/), loaded with dlopen on the first non-PNG
// image read or write, so processes that touch no such file (PNG renders, farm
// workers, most tests) skip OpenImageIO's ~0.25 s of start-up symbol binding. Look-up order: $RAYFARM_IMAGEIO if set, else the
// running executable's directory, else the dynamic loader's search path.
#include "tracer/image_io.h"

#include <dlfcn.h>

#include <array>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <system_error>

#include "tracer/error.h"
#include "tracer/executable_path.h"
#include "tracer/output_file.h"
#include "tracer/oiio/image_io_module.h"
#include "tracer/png_file.h"

namespace rayfarm {
namespace {

namespace fs = std::filesystem;
namespace mod = image_module;

struct ImageModule {
  mod::CheckFn check = nullptr;
  mod::WriteFn write = nullptr;
  mod::ReadFn read = nullptr;
};

std::string dl_error() {
  const char* message = dlerror();
  return message ? message : "unknown dlopen error";
}

// dlopen(path) or nullptr, adding what went wrong to `tried`.
void* open_library(const std::string& path, std::string& tried) {
  dlerror();
  if (void* handle = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL)) return handle;
  // glibc's message usually starts with the path already.
  const std::string error = dl_error();
  tried += (tried.empty() ? " " : "; ") + (error.rfind(path, 0) == 0 ? error : path + ": " + error);
  return nullptr;
}

void* open_module() {
  std::string tried;
  if (const char* override_path = std::getenv(mod::kPathVariable); override_path && *override_path) {
    if (void* handle = open_library(override_path, tried)) return handle;
  } else {
    if (const std::string exe = executable_path(); !exe.empty())
      if (void* handle = open_library((fs::path(exe).parent_path() / mod::kFileName).string(), tried)) return handle;
    // A bare name searches RPATH/RUNPATH, LD_LIBRARY_PATH and the system
    // directories, for an installed rayfarm.
    if (void* handle = open_library(mod::kFileName, tried)) return handle;
  }
  throw std::runtime_error(std::string("cannot load the image module ") + mod::kFileName +
                           " (OpenImageIO); tried:" + tried + " (set " + mod::kPathVariable + " to its path)");
}

template <typename Fn>
Fn symbol(void* handle, const char* name) {
  dlerror();
  void* address = dlsym(handle, name);
  if (!address)
    throw std::runtime_error(std::string("image module ") + mod::kFileName + " lacks " + name + ": " + dl_error());
  return reinterpret_cast<Fn>(address);
}

ImageModule load_module() {
  void* handle = open_module();  // never closed: OpenImageIO keeps threads and caches
  const int abi = symbol<mod::AbiVersionFn>(handle, mod::kAbiVersionSymbol)();
  if (abi != mod::kAbiVersion)
    throw std::runtime_error(std::string("image module ") + mod::kFileName + " has interface version " +
                             std::to_string(abi) + ", expected " + std::to_string(mod::kAbiVersion) +
                             " (rebuild it)");
  return {symbol<mod::CheckFn>(handle, mod::kCheckSymbol), symbol<mod::WriteFn>(handle, mod::kWriteSymbol),
          symbol<mod::ReadFn>(handle, mod::kReadSymbol)};
}

// Loaded once, thread-safely (a function-local static); a failed load throws
// and is retried on the next call.
const ImageModule& loaded_module() {
  static const ImageModule loaded = load_module();
  return loaded;
}

// Calls a module function with an error buffer and rethrows its failure:
// bad input as InputError, anything else as runtime_error.
template <typename Call>
void call_module(Call call) {
  std::array<char, 4096> error{};
  const int status = call(error.data(), error.size());
  if (status == mod::kOk) return;
  if (status == mod::kBadInput) throw InputError(error.data());
  throw std::runtime_error(error.data());
}

float* reserve_rgb(void* image, int width, int height) noexcept {
  auto& out = *static_cast<RgbImage*>(image);
  try {
    out.rgb.resize(static_cast<size_t>(width) * height * 3);
  } catch (...) {
    return nullptr;
  }
  out.width = width;
  out.height = height;
  return out.rgb.data();
}

// The file name must be more than an extension: "-o .png" wrote a hidden
// file named ".png" (libpng's test looks only at the end), and "-o dir/" or
// an existing folder names no file at all.
void check_file_name(const std::string& path) {
  const std::string name = fs::path(path).filename().string();
  std::error_code ec;
  if (name.empty() || name == "." || name == ".." || fs::is_directory(path, ec))
    throw InputError(path + ": names a folder, not an image file (e.g. " + (fs::path(path) / "out.png").string() + ")");
  if (name[0] == '.' && name.find('.', 1) == std::string::npos)
    throw InputError(path + ": no file name before the extension " + name + " (e.g. out" + name + ")");
}

}  // namespace

uint8_t to_8bit(float value) {
  if (!(value > 0)) return 0;  // also NaN
  if (value >= 1) return 255;
  return static_cast<uint8_t>(std::floor(value * 255.0f + 0.5f));
}

void to_8bit(const float* values, size_t count, uint8_t* bytes) {
  for (size_t i = 0; i < count; ++i) bytes[i] = to_8bit(values[i]);
}

void check_image_path(const std::string& path) {
  if (path.empty()) throw InputError("output path is empty");  // OpenImageIO would say "no filename" after ": "
  check_file_name(path);
  if (is_png_path(path)) return;
  const auto check = loaded_module().check;
  call_module([&](char* error, size_t size) { return check(path.c_str(), error, size); });
}

void write_image(const std::string& path, int width, int height, const std::vector<float>& rgb) {
  if (width <= 0 || height <= 0 || rgb.size() != static_cast<size_t>(width) * height * 3)
    throw std::invalid_argument("write_image: rgb does not hold width * height * 3 values");
  check_file_name(path);
  if (is_png_path(path)) {
    std::vector<uint8_t> bytes(rgb.size());
    to_8bit(rgb.data(), bytes.size(), bytes.data());
    return write_atomically(path, [&](const std::string& temp) { write_png(temp, width, height, bytes.data()); });
  }
  const auto write = loaded_module().write;
  write_atomically(path, [&](const std::string& temp) {
    call_module([&](char* error, size_t size) {
      return write(temp.c_str(), width, height, rgb.data(), to_8bit, error, size);
    });
  });
}

RgbImage read_image(const std::string& path) {
  if (is_png_path(path)) {
    RgbImage image;
    const std::vector<uint8_t> bytes = read_png(path, image.width, image.height);
    image.rgb.resize(bytes.size());
    for (size_t i = 0; i < bytes.size(); ++i) image.rgb[i] = bytes[i] / 255.0f;
    return image;
  }
  const auto read = loaded_module().read;
  RgbImage image;
  call_module([&](char* error, size_t size) { return read(path.c_str(), reserve_rgb, &image, error, size); });
  return image;
}

}  // namespace rayfarm
