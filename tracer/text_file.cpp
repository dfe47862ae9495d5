// Whole-file text and JSON IO; see text_file.h.
#include "tracer/text_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <memory>
#include <set>
#include <vector>

#include "tracer/error.h"
#include "tracer/log_text.h"
#include "tracer/output_file.h"

namespace rayfarm {
namespace {

using nlohmann::json;

// nlohmann's DOM builder, except that a number too large for a double
// (1e999) is reported like any syntax error, with its line and column: the
// library raises it as out_of_range 406, which no parse_error handler catches
// and which carries no position. And a key given twice in one object is an
// error: the library keeps the last value, so {"type":"ready","type":"bye"}
// would read as a bye, and a config's first "weight" be silently overridden.
class DomBuilder : public nlohmann::detail::json_sax_dom_parser<nlohmann::json> {
 public:
  DomBuilder(nlohmann::json& root, const std::string& text) : json_sax_dom_parser(root, true), text_(text) {}

  // The keys of each object still open, innermost last (sax_parse calls these
  // in place of the base class's, which it reaches through this type).
  bool start_object(std::size_t size) {
    open_keys_.emplace_back();
    return json_sax_dom_parser::start_object(size);
  }
  bool key(std::string& name) {
    if (!open_keys_.back().insert(name).second)
      throw InputError("duplicate key \"" + quoted_excerpt(name) + "\" in one object");
    return json_sax_dom_parser::key(name);
  }
  bool end_object() {
    open_keys_.pop_back();
    return json_sax_dom_parser::end_object();
  }

  // `end` is the offset just past the offending token.
  template <class Exception>
  bool parse_error(std::size_t end, const std::string& token, const Exception& e) {
    if (e.id != 406) throw e;
    const size_t start = std::min(end, text_.size()) - std::min(end, token.size());
    const size_t line_start = text_.rfind('\n', start == 0 ? 0 : start - 1);
    const size_t column = line_start == std::string::npos || start == 0 ? start + 1 : start - line_start;
    const auto line = 1 + std::count(text_.begin(), text_.begin() + static_cast<std::ptrdiff_t>(start), '\n');
    throw InputError("number out of range at line " + std::to_string(line) + ", column " + std::to_string(column) +
                     ": " + quoted_excerpt(token) + " does not fit a double");
  }

 private:
  const std::string& text_;
  std::vector<std::set<std::string>> open_keys_;
};

// Reads `file` to its end; with `max_bytes`, at most max_bytes + 1 bytes, and
// more is refused as "path: TOO_LARGE". `size`: the file's size, 0 if unknown.
std::string read_to_end(FILE* file, const std::string& path, size_t size, std::optional<size_t> max_bytes,
                        const std::string& too_large) {
  if (max_bytes && size > *max_bytes) throw InputError(path + ": " + too_large);
  std::string text;
  // Sized once: grown by doubling, the string faulted in and copied ever
  // larger buffers (gears' 1.3 MB: parse 8.3 -> 7.7 ms).
  text.reserve(size);
  char buf[1 << 16];
  size_t got = 0;
  while ((got = std::fread(buf, 1, max_bytes ? std::min(sizeof buf, *max_bytes - text.size() + 1) : sizeof buf,
                           file)) > 0) {
    text.append(buf, got);
    if (max_bytes && text.size() > *max_bytes)  // a file that grew after fstat, a pipe, a device
      throw InputError(path + ": " + too_large);
  }
  if (std::ferror(file)) throw InputError(path + ": cannot read (" + std::strerror(errno) + ")");
  return text;
}

using File = std::unique_ptr<FILE, int (*)(FILE*)>;

// `nonblocking`: for a caller that takes regular files only. Opening a FIFO
// waits for a writer: a FIFO named *.pub in an allow folder, or given as a
// key or config file, held the broker or worker at start for good, saying
// nothing. Opened without waiting, it is refused as not a regular file.
File open_file(const std::string& path, bool nonblocking = false) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | (nonblocking ? O_NONBLOCK : 0));
  if (fd < 0) throw InputError(path + ": cannot open (" + std::strerror(errno) + ")");
  File file(::fdopen(fd, "rb"), &std::fclose);
  if (!file) {
    const int error = errno;
    ::close(fd);
    throw InputError(path + ": cannot open (" + std::strerror(error) + ")");
  }
  return file;
}

// The size of a regular file, or nullopt for anything else (a pipe, a device, a folder).
std::optional<size_t> regular_file_size(FILE* file) {
  struct stat st {};
  if (fstat(fileno(file), &st) != 0 || !S_ISREG(st.st_mode)) return std::nullopt;
  return static_cast<size_t>(st.st_size);
}

}  // namespace

std::string read_text_file(const std::string& path, std::optional<size_t> max_bytes) {
  const File file = open_file(path, max_bytes.has_value());
  const std::optional<size_t> size = regular_file_size(file.get());
  if (max_bytes && !size) throw InputError(path + ": not a regular file");
  const std::string too_large = max_bytes ? "larger than " + std::to_string(*max_bytes) + " bytes" : "";
  return read_to_end(file.get(), path, size.value_or(0), max_bytes, too_large);
}

std::string read_text_file_within(const std::string& path, size_t max_bytes, const std::string& limit) {
  const File file = open_file(path);
  const size_t size = regular_file_size(file.get()).value_or(0);
  return read_to_end(file.get(), path, size, max_bytes, "larger than the " + limit);
}

nlohmann::json read_json_file(const std::string& path, std::optional<size_t> max_bytes) {
  return parse_json_text(read_text_file(path, max_bytes), path);
}

nlohmann::json parse_json_text(const std::string& text, const std::string& name) {
  nlohmann::json root;
  try {
    DomBuilder builder(root, text);
    nlohmann::json::sax_parse(text, &builder);
  } catch (const nlohmann::json::exception& e) {
    throw InputError(name + ": invalid JSON: " + short_json_error(e.what()));
  } catch (const InputError& e) {
    throw InputError(name + ": invalid JSON: " + e.what());
  }
  return root;
}

namespace {

bool is_continuation(const std::string& text, size_t i) {
  return (static_cast<unsigned char>(text[i]) & 0xc0) == 0x80;
}

// Where an excerpt of at most `max_bytes` of `text` (longer than that) ends:
// not inside a UTF-8 character, whose first bytes alone are no text a JSON
// answer can carry. Stepping back at most 3 bytes, a character's most: a run
// of bytes that are no UTF-8 (0x80 0x80 ...) is cut where it falls.
size_t excerpt_end(const std::string& text, size_t max_bytes) {
  size_t end = max_bytes;
  while (end > 0 && max_bytes - end < 3 && is_continuation(text, end)) --end;
  return is_continuation(text, end) ? max_bytes : end;
}

// Where an excerpt of at most the last `max_bytes` of `text` (longer than
// that) begins: likewise not inside a UTF-8 character.
size_t excerpt_start(const std::string& text, size_t max_bytes) {
  const size_t start = text.size() - max_bytes;
  size_t at = start;
  while (at < text.size() && at - start < 3 && is_continuation(text, at)) ++at;
  return at < text.size() && is_continuation(text, at) ? start : at;
}

// `value` written as compact JSON, but each string (a key too) as it is,
// between quotes, without JSON's escapes: the message that quotes it is
// escaped once, where it is printed (tracer/log_text.h), and an escape of
// JSON's own came out of it escaped again ("a\\u001bb" for an ESC). A byte
// that is not UTF-8 is U+FFFD, as JSON would carry it. Stops once `out` holds
// more than `limit` bytes: the excerpt is cut there anyway.
void append_unescaped(const nlohmann::json& value, std::string& out, size_t limit) {
  const auto quoted = [&](const std::string& text) { out += '"' + valid_utf8(text) + '"'; };
  if (value.is_string()) {
    quoted(value.get_ref<const std::string&>());
  } else if (value.is_array()) {
    out += '[';
    for (auto it = value.begin(); it != value.end() && out.size() <= limit; ++it) {
      if (it != value.begin()) out += ',';
      append_unescaped(*it, out, limit);
    }
    out += ']';
  } else if (value.is_object()) {
    out += '{';
    for (auto it = value.begin(); it != value.end() && out.size() <= limit; ++it) {
      if (it != value.begin()) out += ',';
      quoted(it.key());
      out += ':';
      append_unescaped(it.value(), out, limit);
    }
    out += '}';
  } else {
    out += value.dump();  // a number as written (2.0, 1e+30), true, false, null
  }
}

}  // namespace

std::string quoted_excerpt(const std::string& text, size_t max_bytes) {
  std::string out = text.size() > max_bytes ? text.substr(0, excerpt_end(text, max_bytes)) + "..." : text;
  for (size_t nul = out.find('\0'); nul != std::string::npos; nul = out.find('\0', nul))
    out.replace(nul, 1, "\xef\xbf\xbd");
  return out;
}

std::string middle_excerpt(const std::string& text, size_t max_bytes, size_t head, const std::string& gap) {
  if (text.size() <= max_bytes) return text;
  const size_t tail = max_bytes - head - gap.size();
  return text.substr(0, excerpt_end(text, head)) + gap + text.substr(excerpt_start(text, tail));
}

std::string json_excerpt(const nlohmann::json& value, size_t max_bytes) {
  std::string text;
  append_unescaped(value, text, max_bytes);
  return quoted_excerpt(text, max_bytes);
}

std::string short_json_error(const std::string& what) {
  std::string out = what;
  for (const std::string marker : {"last read: '", "overflow parsing '"}) {
    const size_t at = out.find(marker);
    if (at == std::string::npos) continue;
    const size_t from = at + marker.size();
    // The token ends at the quote before the library's own tail, a token
    // kind ("; expected '[', '{', or a literal"), or at the closing quote.
    // The token itself may hold "'; expected ": the real tail is short.
    size_t end = out.rfind("'; expected ");
    if (end == std::string::npos || end < from || out.size() - end > 64)
      end = out.back() == '\'' && out.size() > from ? out.size() - 1 : out.size();
    out = out.substr(0, from) + quoted_excerpt(out.substr(from, end - from)) + out.substr(end);
  }
  return out;
}

void write_text_file(const std::string& path, const std::string& text) {
  write_atomically(path, [&](const std::string& temp) {
    errno = 0;
    std::ofstream out(temp, std::ios::binary);
    // The stream keeps no reason; the failed open or write(2) left it in errno
    // (a full disk, a file-size limit), which an operator needs to act on.
    if (!out || !(out << text) || !out.flush())
      throw InputError(path + ": cannot write" + (errno ? std::string(" (") + std::strerror(errno) + ")" : ""));
  });
}

void write_json_file(const std::string& path, const nlohmann::json& json) {
  write_text_file(path, json.dump(2) + "\n");
}

}  // namespace rayfarm
