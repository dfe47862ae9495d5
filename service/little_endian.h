// Little-endian u32 fields of the service's binary files (the journal's
// record headers, the frame header): byte by byte, so the files read the same
// on any host.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

namespace rayfarm {

inline void put_u32(std::string& out, uint32_t v) {
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<char>((v >> (8 * i)) & 0xff));
}

// `bytes` must hold 4 bytes at `at`.
inline uint32_t get_u32(std::string_view bytes, size_t at) {
  uint32_t v = 0;
  for (int i = 0; i < 4; ++i) v |= uint32_t{static_cast<unsigned char>(bytes[at + i])} << (8 * i);
  return v;
}

}  // namespace rayfarm
