// Whole-file text and JSON IO with errors that name the file. Scenes, configs,
// stats files, job records, cost profiles and reports all go through here.
// Files from outside can be bounded: a config naming /dev/zero or a FIFO must
// fail at once, not read forever. Writes are atomic (tracer/output_file.h).
#pragma once

#include <cstddef>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

namespace rayfarm {

// The file's bytes; InputError "path: cannot open (reason)" / "cannot read".
// With `max_bytes`, the path must name a regular file of at most that size.
std::string read_text_file(const std::string& path, std::optional<size_t> max_bytes = std::nullopt);

// InputError as read_text_file, or "path: invalid JSON: ...", or for a number
// JSON cannot hold "path: key.path: number overflow (1e999)".
nlohmann::json read_json_file(const std::string& path, std::optional<size_t> max_bytes = std::nullopt);

// Writes `text` to `path` atomically; InputError "path: cannot write" on failure.
void write_text_file(const std::string& path, const std::string& text);

// Writes `json` pretty-printed (indent 2) with a final newline.
void write_json_file(const std::string& path, const nlohmann::json& json);

}  // namespace rayfarm
