// Tiny NFF scenes for the service tests: each frame of an "animation" moves
// the sphere, so frames differ and a mix-up between them shows in the bytes.
#pragma once

#include <string>

namespace rayfarm::test {

inline std::string tiny_scene(int frame = 0, int width = 32, int height = 24) {
  return "b 0.1 0.2 0.3\nv\nfrom 0 0 5\nat 0 0 0\nup 0 1 0\nangle 45\nhither 1\nresolution " +
         std::to_string(width) + " " + std::to_string(height) +
         "\nl 5 5 5\nf 1 0.5 0.2 0.7 0.3 10 0 1\ns " + std::to_string(0.2 * frame - 0.2) + " 0 0 1\n";
}

}  // namespace rayfarm::test
