// Reading a whole JSON document from a file for the replay's inputs (lab
// files, cost profiles, job records), with errors that name the file.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

namespace rayfarm {

// InputError "path: cannot open" / "path: invalid JSON: ...".
nlohmann::json read_json_file(const std::string& path);

// Writes `text` to `path`; InputError "path: cannot write" on failure.
void write_text_file(const std::string& path, const std::string& text);

}  // namespace rayfarm
