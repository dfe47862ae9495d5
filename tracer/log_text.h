// Text from the network made safe for a log line: the broker's log and a
// worker's both print what peers send.
#pragma once

#include <cstdio>
#include <string>

namespace rayfarm {

namespace log_text_detail {

// The length of the well-formed UTF-8 sequence at text[i] (RFC 3629: no
// overlong forms, no surrogates, nothing past U+10FFFF), or 0.
inline size_t utf8_length(const std::string& text, size_t i) {
  const auto at = [&](size_t k) { return i + k < text.size() ? static_cast<unsigned char>(text[i + k]) : 0u; };
  const auto follows = [&](size_t k, unsigned low = 0x80, unsigned high = 0xbf) {
    return at(k) >= low && at(k) <= high;
  };
  const unsigned c = at(0);
  if (c < 0x80) return 1;
  if (c >= 0xc2 && c <= 0xdf) return follows(1) ? 2 : 0;
  if (c == 0xe0) return follows(1, 0xa0) && follows(2) ? 3 : 0;
  if (c == 0xed) return follows(1, 0x80, 0x9f) && follows(2) ? 3 : 0;  // not a surrogate
  if (c >= 0xe1 && c <= 0xef) return follows(1) && follows(2) ? 3 : 0;
  if (c == 0xf0) return follows(1, 0x90) && follows(2) && follows(3) ? 4 : 0;
  if (c >= 0xf1 && c <= 0xf3) return follows(1) && follows(2) && follows(3) ? 4 : 0;
  if (c == 0xf4) return follows(1, 0x80, 0x8f) && follows(2) && follows(3) ? 4 : 0;
  return 0;
}

// The code point of the well-formed UTF-8 sequence of `length` bytes
// (utf8_length's, not 0) at text[i].
inline unsigned utf8_code_point(const std::string& text, size_t i, size_t length) {
  static const unsigned kLeadBits[] = {0, 0x7f, 0x1f, 0x0f, 0x07};
  unsigned code_point = static_cast<unsigned char>(text[i]) & kLeadBits[length];
  for (size_t k = 1; k < length; ++k) code_point = code_point << 6 | (static_cast<unsigned char>(text[i + k]) & 0x3fu);
  return code_point;
}

// Format characters that change how a line reads without being seen, each
// written as an escape: the one table of them. The bidi embeddings and
// overrides (U+202A..U+202E) and isolates (U+2066..U+2069) show what follows
// them reversed or moved ("evil\u202egnp.exe" reads "evilexe.png"), and so do
// the bidi marks (U+200E, U+200F, the Arabic letter mark U+061C) within text of
// the other direction; the line and paragraph separators (U+2028, U+2029)
// break the line where a terminal or viewer honours them; the rest print as
// nothing and make two names that print alike differ ("worker\u200b1" is not
// "worker1"), or hide text a reader cannot see.
struct CodePoints {
  unsigned first, last;
};
inline constexpr CodePoints kInvisibleFormat[] = {
    {0x00ad, 0x00ad},    // soft hyphen: seen only where a line breaks at it
    {0x061c, 0x061c},    // Arabic letter mark
    {0x180e, 0x180e},    // Mongolian vowel separator, of no width since Unicode 6.3
    {0x200b, 0x200f},    // zero-width space, non-joiner and joiner; the left-to-right and right-to-left marks
    {0x2028, 0x202e},    // line and paragraph separators; bidi embeddings, pop and overrides
    {0x2060, 0x2064},    // word joiner, invisible operators
    {0x2066, 0x2069},    // bidi isolates
    {0x206a, 0x206f},    // the deprecated format characters (symmetric swapping, Arabic shaping, digit shapes)
    {0xfeff, 0xfeff},    // zero-width no-break space, the byte-order mark
    {0xe0000, 0xe007f},  // tags: an unseen copy of ASCII text ("worker1" spelled in tags prints as nothing)
};

inline bool is_invisible_format(unsigned code_point) {
  for (const CodePoints& range : kInvisibleFormat)
    if (code_point >= range.first && code_point <= range.last) return true;
  return false;
}

}  // namespace log_text_detail

// Log lines carry text from the network (worker names, failure reasons, job
// and scene names; the broker's reasons in a worker's log): a newline or
// carriage return in it would forge log lines, an ESC drive the terminal.
// Control characters (C0, DEL, and C1 as UTF-8) and the invisible format
// characters (is_invisible_format: bidi controls and marks, line separators,
// zero-width characters, which make a line read other than it is) are
// written as escapes instead: \n, \r, \t, \x1b, \u009b, \u202e, \u200b, and
// past U+FFFF with eight digits, \U000e0041, which four would misread;
// and a backslash as \\, or a name with a real newline and one spelled "\n"
// would read alike.
// A byte that is not part of well-formed UTF-8 (a JSON parse error quotes
// what it read, raw) is written \xff too: journald shows a line holding one
// as "[blob data]", which would hide the rest of the line, a peer's own
// rejection with it.
inline std::string escape_control_characters(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  char escape[16];
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
    } else if (c < 0x80) {
      out += text[i];
    } else if (const size_t length = log_text_detail::utf8_length(text, i); length == 0) {
      std::snprintf(escape, sizeof escape, "\\x%02x", c);
      out += escape;
    } else if (c == 0xc2 && next <= 0x9f) {  // U+0080..U+009F
      std::snprintf(escape, sizeof escape, "\\u%04x", next);
      out += escape;
      ++i;
    } else if (const unsigned code_point = log_text_detail::utf8_code_point(text, i, length);
               log_text_detail::is_invisible_format(code_point)) {
      if (code_point > 0xffff)
        std::snprintf(escape, sizeof escape, "\\U%08x", code_point);
      else
        std::snprintf(escape, sizeof escape, "\\u%04x", code_point);
      out += escape;
      i += length - 1;
    } else {
      out.append(text, i, length);
      i += length - 1;
    }
  }
  return out;
}

// `text` with each byte that is not part of well-formed UTF-8 replaced by
// U+FFFD: the only text JSON carries (a message, a job record), where such a
// byte makes nlohmann::json::dump() throw.
inline std::string valid_utf8(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  for (size_t i = 0; i < text.size();) {
    const size_t length = log_text_detail::utf8_length(text, i);
    if (length == 0) {
      out += "\xef\xbf\xbd";
      ++i;
    } else {
      out.append(text, i, length);
      i += length;
    }
  }
  return out;
}

}  // namespace rayfarm
