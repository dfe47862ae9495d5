// The C interface between image_io.cpp and the OpenImageIO module
// (librayfarm_imageio.so), which image_io.cpp loads with dlopen on the first
// image read or write: linking OpenImageIO's large dependency tree into every
// process costs ~0.25 s of symbol binding at start-up, paid by every farm
// worker and test run although only image files need it.
// Plain C types only, and no exception crosses the boundary: each function
// returns a status and writes a one-line message into the caller's buffer.
#pragma once

#include <cstddef>
#include <cstdint>

namespace rayfarm::image_module {

// File name of the module, looked up beside the running executable first.
constexpr const char* kFileName = "librayfarm_imageio.so";
// Environment variable naming the module file, overriding the look-up.
constexpr const char* kPathVariable = "RAYFARM_IMAGEIO";
// Bumped whenever a signature below changes, so a stale module is refused.
constexpr int kAbiVersion = 1;

// Status codes of the functions below.
enum Status : int { kOk = 0, kBadInput = 1, kInternal = 2 };

// Caller-owned storage for a read image: returns room for width * height * 3
// floats, or nullptr if it cannot be had. Must not throw.
using ReserveRgb = float* (*)(void* image, int width, int height);
// Linear value -> stored 8-bit value (image_io.h's to_8bit). Must not throw.
using Quantise = uint8_t (*)(float value);

using AbiVersionFn = int (*)();
using CheckFn = int (*)(const char* path, char* error, size_t error_size);
using WriteFn = int (*)(const char* path, int width, int height, const float* rgb, Quantise quantise,
                        char* error, size_t error_size);
using ReadFn = int (*)(const char* path, ReserveRgb reserve, void* image, char* error, size_t error_size);

// Exported symbol names (extern "C" in the module).
constexpr const char* kAbiVersionSymbol = "rayfarm_imageio_abi_version";
constexpr const char* kCheckSymbol = "rayfarm_imageio_check";
constexpr const char* kWriteSymbol = "rayfarm_imageio_write";
constexpr const char* kReadSymbol = "rayfarm_imageio_read";

}  // namespace rayfarm::image_module
