// Small files for tests: a per-process scratch folder and a tiny scene that
// exercises every code path of a render (two spheres, a polygon, a light).
#pragma once

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

namespace rayfarm::test {

// A fresh folder under the system temp dir, unique per test process and tag.
inline std::filesystem::path scratch_dir(const std::string& tag) {
  std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("rayfarm-" + tag + "-" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

inline std::string write_file(const std::filesystem::path& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
  return path.string();
}

// 16x12 pixels: renders in milliseconds.
inline const char* tiny_scene() {
  return "b 0.1 0.2 0.3\nv\nfrom 0 -4 1\nat 0 0 0\nup 0 0 1\nangle 40\nhither 0.01\nresolution 16 12\n"
         "l 3 -3 5\nf 1 0.5 0.5 0.8 0.3 20 0 1\ns -0.6 0 0 0.5\ns 0.6 0 0 0.5\n"
         "f 0.8 0.8 0.8 1 0 0 0 1\np 4\n-3 -3 -0.5\n3 -3 -0.5\n3 3 -0.5\n-3 3 -0.5\n";
}

}  // namespace rayfarm::test
