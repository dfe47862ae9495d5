// Where tests find the source tree, the shared reference data and the rayfarm
// executable (set by CMake).
#pragma once

#include <string>

namespace rayfarm::test {
inline std::string source_dir() { return RAYFARM_SOURCE_DIR; }
inline std::string shared_dir() { return RAYFARM_SHARED_DIR; }
inline std::string rayfarm_exe() { return RAYFARM_EXE; }
}  // namespace rayfarm::test
