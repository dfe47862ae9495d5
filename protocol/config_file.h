// Reading a JSON config file strictly: the file must parse, the callback reads
// the fields it knows through JsonFields, and any key left over is an error.
// Every error reads "path: key.path: reason". Only regular files of at most
// kMaxConfigBytes are read (a config is a few hundred bytes; /dev/zero is not one).
// The text variant is the same check for JSON that is already in memory (and
// what the fuzz targets drive).
#pragma once

#include <cstddef>

#include <functional>
#include <initializer_list>
#include <string>

#include "protocol/json_fields.h"

namespace rayfarm {

inline constexpr size_t kMaxConfigBytes = 1 << 20;

void read_config_file(const std::string& path, const std::function<void(JsonFields&)>& read_fields);
// Makes each non-empty relative path in `paths` relative to the folder of
// the config file that named it (keys, allow folders), not to the cwd.
void resolve_beside_config(const std::string& config_path, std::initializer_list<std::string*> paths);

void read_config_text(const std::string& text, const std::string& name,
                      const std::function<void(JsonFields&)>& read_fields);

}  // namespace rayfarm
