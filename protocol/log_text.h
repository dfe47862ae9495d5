// Text from the network made safe for a log line: the broker's log and a
// worker's both print what peers send.
#pragma once

#include <cstdio>
#include <string>

namespace rayfarm {

// Log lines carry text from the network (worker names, failure reasons, job
// and scene names; the broker's reasons in a worker's log): a newline or
// carriage return in it would forge log lines, an ESC drive the terminal. Control characters (C0, DEL, and C1 as UTF-8)
// are written as escapes instead: \n, \r, \t, \x1b, \u009b; and a backslash
// as \\, or a name with a real newline and one spelled "\n" would read alike.
inline std::string escape_control_characters(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  char escape[8];
  for (size_t i = 0; i < text.size(); ++i) {
    const auto c = static_cast<unsigned char>(text[i]);
    const auto next = i + 1 < text.size() ? static_cast<unsigned char>(text[i + 1]) : 0;
    if (c == '\\') {
      out += "\\\\";
    } else if (c == '\n') {
      out += "\\n";
    } else if (c == '\r') {
      out += "\\r";
    } else if (c == '\t') {
      out += "\\t";
    } else if (c < 0x20 || c == 0x7f) {
      std::snprintf(escape, sizeof escape, "\\x%02x", c);
      out += escape;
    } else if (c == 0xc2 && next >= 0x80 && next <= 0x9f) {  // U+0080..U+009F
      std::snprintf(escape, sizeof escape, "\\u%04x", next);
      out += escape;
      ++i;
    } else {
      out += text[i];
    }
  }
  return out;
}

}  // namespace rayfarm
