// Where the running program lives, for what is installed beside it: the
// image module, rayfarm-farm, worker processes started by a local farm.
#pragma once

#include <string>

namespace rayfarm {

// The running executable (/proc/self/exe), or "" where it cannot be read.
std::string executable_path();

}  // namespace rayfarm
