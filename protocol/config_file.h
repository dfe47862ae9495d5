// Reading a JSON config file strictly: the file must parse, the callback reads
// the fields it knows through JsonFields, and any key left over is an error.
// Every error reads "path: key.path: reason". Only regular files of at most
// kMaxConfigBytes are read (a config is a few hundred bytes; /dev/zero is not one).
#pragma once

#include <cstddef>

#include <functional>
#include <string>

#include "protocol/json_fields.h"

namespace rayfarm {

inline constexpr size_t kMaxConfigBytes = 1 << 20;

void read_config_file(const std::string& path, const std::function<void(JsonFields&)>& read_fields);

}  // namespace rayfarm
