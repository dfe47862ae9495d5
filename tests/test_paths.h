// Where tests find the source tree, the in-repo reference scenes and the
// rayfarm executable (set by CMake). Tests read only files inside the repo, so a
// clone with nothing beside it passes.
#pragma once

#include <string>

namespace rayfarm::test {
inline std::string source_dir() { return RAYFARM_SOURCE_DIR; }
// Small SPD reference outputs (sizes 1 and 2), e.g. spd_data("balls-2").
inline std::string spd_data(const std::string& stem) { return source_dir() + "/tests/data/spd/" + stem + ".nff"; }
// The five paper scenes at their default sizes, e.g. paper_scene("balls").
inline std::string paper_scene(const std::string& name) { return source_dir() + "/scenes/" + name + ".nff"; }
inline std::string rayfarm_exe() { return RAYFARM_EXE; }
}  // namespace rayfarm::test
