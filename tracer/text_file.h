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

// The bytes of `path`, a file of any kind (a pipe from `<(...)` as well), if at
// most `max_bytes`: it reads at most max_bytes + 1 bytes, so that /dev/zero or
// a FIFO of endless data is refused at once, not read until memory runs out.
// InputError "path: larger than the LIMIT" (`limit` names max_bytes to the
// user, e.g. "256 MiB scene limit"), or as read_text_file.
std::string read_text_file_within(const std::string& path, size_t max_bytes, const std::string& limit);

// InputError as read_text_file, or "path: invalid JSON: ..." (a number too
// large for a double included, with its line and column).
nlohmann::json read_json_file(const std::string& path, std::optional<size_t> max_bytes = std::nullopt);

// Parses JSON text that came from `name`, with the same errors as read_json_file.
nlohmann::json parse_json_text(const std::string& text, const std::string& name);

// Text quoted from input into an error message, kept short: its first
// `max_bytes` (not cutting a UTF-8 character) and "...", or all of it if it
// is no longer. A cut scene or a key of a megabyte is named by its start.
// Quoted as it is: what prints the message escapes it (a log line, the
// command line's error), once. Only a NUL is written U+FFFD: it would end
// the message there (what() is a C string), closing quote and all.
std::string quoted_excerpt(const std::string& text, size_t max_bytes = 80);

// Text cut to at most `max_bytes` in its middle, for a field that must hold
// it whole: its first `head` bytes, `gap`, then as much of its end as fits,
// neither part cutting a UTF-8 character; all of it if it fits. An error keeps
// where it began (a file's name) and what it says (the line and message).
std::string middle_excerpt(const std::string& text, size_t max_bytes, size_t head, const std::string& gap = " [...] ");

// A JSON value as it was written (a whole number with a point, a number in
// quotes), for an error message: compact JSON whose strings are quoted as
// they are, without JSON's escapes (what prints the message escapes them,
// once: an ESC reads "a\x1bb", not "a\\u001bb"), a byte that is not UTF-8 as
// U+FFFD, and cut as quoted_excerpt cuts.
std::string json_excerpt(const nlohmann::json& value, size_t max_bytes = 40);

// The JSON library's error message `what` with the token it quotes ("last
// read: '...'", "overflow parsing '...'") cut by quoted_excerpt: the library
// quotes the whole token it was reading, and in a cut submission.json that is
// the scene, megabytes of it, in one log line or API answer.
std::string short_json_error(const std::string& what);

// Writes `text` to `path` atomically; InputError "path: cannot write" on failure.
void write_text_file(const std::string& path, const std::string& text);

// Writes `json` pretty-printed (indent 2) with a final newline.
void write_json_file(const std::string& path, const nlohmann::json& json);

}  // namespace rayfarm
