// Whole-file text and JSON IO; see text_file.h.
#include "tracer/text_file.h"

#include <sys/stat.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <memory>
#include <vector>

#include "tracer/error.h"
#include "tracer/output_file.h"

namespace rayfarm {
namespace {

using nlohmann::json;

// Where the JSON parser is, as a key path ("machines[2].count"), kept up to
// date from the parser's callback so an error thrown mid-value (number
// overflow has no position of its own) can still name its key.
class JsonKeyTracker {
 public:
  bool on_event(json::parse_event_t event, const json& parsed) {
    switch (event) {
      case json::parse_event_t::object_start:
      case json::parse_event_t::array_start:
        if (!frames_.empty() && frames_.back().array) ++frames_.back().elements;  // a container element began
        frames_.push_back({event == json::parse_event_t::array_start, 0, ""});
        break;
      case json::parse_event_t::object_end:
      case json::parse_event_t::array_end:
        if (!frames_.empty()) frames_.pop_back();
        break;
      case json::parse_event_t::key:
        if (!frames_.empty() && parsed.is_string()) frames_.back().key = parsed.get<std::string>();
        break;
      case json::parse_event_t::value:  // a scalar ended
        if (!frames_.empty() && frames_.back().array) ++frames_.back().elements;
        break;
    }
    return true;
  }

  // The value being parsed when an exception interrupted the parser: an
  // array's index is its last begun container element, or for the innermost
  // array the scalar after its finished elements.
  std::string path() const {
    std::string out;
    for (size_t i = 0; i < frames_.size(); ++i) {
      const Frame& f = frames_[i];
      const bool innermost = i + 1 == frames_.size();
      if (f.array)
        out += "[" + std::to_string(innermost ? f.elements : f.elements - 1) + "]";
      else if (!f.key.empty())
        out += (out.empty() ? "" : ".") + f.key;
    }
    return out;
  }

 private:
  struct Frame {
    bool array;
    size_t elements;  // array: elements begun so far
    std::string key;  // object: the key being parsed
  };
  std::vector<Frame> frames_;
};

}  // namespace

std::string read_text_file(const std::string& path, std::optional<size_t> max_bytes) {
  std::unique_ptr<FILE, int (*)(FILE*)> file(std::fopen(path.c_str(), "rb"), &std::fclose);
  if (!file) throw InputError(path + ": cannot open (" + std::strerror(errno) + ")");
  if (max_bytes) {
    struct stat st {};
    if (fstat(fileno(file.get()), &st) != 0 || !S_ISREG(st.st_mode))
      throw InputError(path + ": not a regular file");
    if (static_cast<uint64_t>(st.st_size) > *max_bytes)
      throw InputError(path + ": larger than " + std::to_string(*max_bytes) + " bytes");
  }
  std::string text;
  char buf[1 << 16];
  size_t got = 0;
  while ((got = std::fread(buf, 1, sizeof buf, file.get())) > 0) {
    text.append(buf, got);
    if (max_bytes && text.size() > *max_bytes)  // the file grew after fstat
      throw InputError(path + ": larger than " + std::to_string(*max_bytes) + " bytes");
  }
  if (std::ferror(file.get())) throw InputError(path + ": cannot read (" + std::strerror(errno) + ")");
  return text;
}

nlohmann::json read_json_file(const std::string& path, std::optional<size_t> max_bytes) {
  const std::string text = read_text_file(path, max_bytes);
  JsonKeyTracker where;
  try {
    return json::parse(text, [&](int, json::parse_event_t event, json& parsed) { return where.on_event(event, parsed); });
  } catch (const json::parse_error& e) {
    throw InputError(path + ": invalid JSON: " + e.what());
  } catch (const json::exception& e) {
    const std::string key = where.path();
    std::string what = e.what();
    if (const size_t bracket = what.find("] "); bracket != std::string::npos) what = what.substr(bracket + 2);
    throw InputError(path + ": " + (key.empty() ? "" : key + ": ") + what);
  }
}

void write_text_file(const std::string& path, const std::string& text) {
  write_atomically(path, [&](const std::string& temp) {
    std::ofstream out(temp, std::ios::binary);
    if (!out || !(out << text) || !out.flush()) throw InputError(path + ": cannot write");
  });
}

void write_json_file(const std::string& path, const nlohmann::json& json) {
  write_text_file(path, json.dump(2) + "\n");
}

}  // namespace rayfarm
