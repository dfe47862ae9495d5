// Whole-file text and JSON IO with errors that name the file. Scenes, configs,
// stats files, job records, cost profiles and reports all go through here.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

namespace rayfarm {

// The file's bytes; InputError "path: cannot open (reason)" / "cannot read".
std::string read_text_file(const std::string& path);

// InputError as read_text_file, or "path: invalid JSON: ...".
nlohmann::json read_json_file(const std::string& path);

// Parses JSON text that came from `name`; InputError "name: invalid JSON: ...".
nlohmann::json parse_json_text(const std::string& text, const std::string& name);

// Writes `text` to `path`; InputError "path: cannot write" on failure.
void write_text_file(const std::string& path, const std::string& text);

// Writes `json` pretty-printed (indent 2) with a final newline.
void write_json_file(const std::string& path, const nlohmann::json& json);

}  // namespace rayfarm
