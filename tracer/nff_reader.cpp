// NFF parsing: a lexer that yields whitespace-separated tokens with their line
// numbers, and a parser that reads a fixed count of numbers per entity (the
// SPD's `c` puts all eight numbers on one line, the NFF document on three).
// Numbers go through std::from_chars: no locale, no iostream per token, so a
// 25 MB balls-6 file parses in well under a second.
#include "tracer/nff_reader.h"

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <memory>

#include "tracer/error.h"
#include "tracer/text_file.h"
#include "tracer/triangulate.h"

namespace rayfarm {
namespace {

// Past this many, warnings are counted instead of listed (a file with thousands
// of degenerate triangles should not flood stderr).
constexpr size_t kMaxListedWarnings = 50;
constexpr int kMaxResolution = 65536;

// A line ends at LF, CRLF or a lone CR (classic Mac OS text, where NFF files
// from the SPD's era were also written): a comment stops there, and the CR of a
// CRLF is counted with its LF.
bool is_blank(char c) { return c == ' ' || c == '\t' || c == '\v' || c == '\f'; }
bool is_line_end(char c) { return c == '\n' || c == '\r'; }
bool is_space(char c) { return is_line_end(c) || is_blank(c); }
bool ends_token(char c) { return is_space(c) || c == '#'; }

struct Token {
  std::string_view text;  // empty at end of input
  int line = 0;
  bool at_end() const { return text.empty(); }
};

// Some Windows editors begin UTF-8 text with a byte-order mark. It is no
// token, and it holds no newline, so skipping it keeps every line number.
constexpr std::string_view kUtf8ByteOrderMark = "\xEF\xBB\xBF";

class Lexer {
 public:
  explicit Lexer(std::string_view text) : text_(text) {
    if (text_.substr(0, kUtf8ByteOrderMark.size()) == kUtf8ByteOrderMark) pos_ = kUtf8ByteOrderMark.size();
  }

  Token next() {
    skip_blanks_and_comments();
    const size_t start = pos_;
    while (pos_ < text_.size() && !ends_token(text_[pos_])) ++pos_;
    return {text_.substr(start, pos_ - start), line_};
  }

  // The next token if it is on the current line (not consumed), else empty.
  std::string_view peek_on_line() const {
    size_t p = pos_;
    while (p < text_.size() && is_blank(text_[p])) ++p;
    const size_t start = p;
    while (p < text_.size() && !ends_token(text_[p])) ++p;
    return text_.substr(start, p - start);
  }

  int line() const { return line_; }

 private:
  void skip_blanks_and_comments() {
    while (pos_ < text_.size()) {
      const char c = text_[pos_];
      if (is_line_end(c)) {
        ++pos_;
        if (!(c == '\r' && pos_ < text_.size() && text_[pos_] == '\n')) ++line_;
      } else if (is_blank(c)) {
        ++pos_;
      } else if (c == '#') {
        while (pos_ < text_.size() && !is_line_end(text_[pos_])) ++pos_;
      } else {
        break;
      }
    }
  }

  std::string_view text_;
  size_t pos_ = 0;
  int line_ = 1;
};

enum class NumberKind { ok, not_a_number, not_finite };

// Clinger's fast path (W. D. Clinger, "How to Read Floating Point Numbers
// Accurately", PLDI 1990): a plain decimal with at most 15 significant digits
// and at most 22 fraction digits is m / 10^k with both operands exact doubles,
// so one IEEE division is correctly rounded -- the same bits as strtod. Covers
// every number the SPD writes with %g except exponents, at ~4x from_chars' speed.
bool parse_plain_decimal(const char* p, const char* end, double& value) {
  static constexpr double kPow10[] = {1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,
                                      1e8,  1e9,  1e10, 1e11, 1e12, 1e13, 1e14, 1e15,
                                      1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};
  const bool negative = p != end && *p == '-';
  p += negative;
  uint64_t mantissa = 0;
  int significant = 0, fraction = 0;
  bool dot = false, digit = false;
  for (; p != end; ++p) {
    if (*p >= '0' && *p <= '9') {
      mantissa = mantissa * 10 + static_cast<uint64_t>(*p - '0');
      significant += mantissa != 0;
      fraction += dot;
      digit = true;
      if (significant > 15) return false;
    } else if (*p == '.' && !dot) {
      dot = true;
    } else {
      return false;
    }
  }
  if (!digit || fraction > 22) return false;
  value = static_cast<double>(mantissa) / kPow10[fraction];
  if (negative) value = -value;
  return true;
}

NumberKind parse_double(std::string_view s, double& value) {
  const char* begin = s.data();
  const char* end = begin + s.size();
  if (begin != end && *begin == '+' && end - begin > 1 && begin[1] != '-') ++begin;  // from_chars rejects '+'
  if (parse_plain_decimal(begin, end, value)) return NumberKind::ok;
  const auto [ptr, ec] = std::from_chars(begin, end, value);
  if (ec == std::errc::result_out_of_range && ptr == end) {
    // Overflow is an error; underflow (1e-400) is a legitimate tiny number.
    value = std::strtod(std::string(begin, end).c_str(), nullptr);
    return std::isfinite(value) ? NumberKind::ok : NumberKind::not_finite;
  }
  if (ec != std::errc() || ptr != end) return NumberKind::not_a_number;
  return std::isfinite(value) ? NumberKind::ok : NumberKind::not_finite;
}

bool parse_int(std::string_view s, int& value) {
  const char* end = s.data() + s.size();
  const auto [ptr, ec] = std::from_chars(s.data(), end, value);
  return ec == std::errc() && ptr == end;
}

// A token as it appears in a message: quoted and shortened. UTF-8 is kept as
// written ("1\u00e9" was "1??"), and so is the rest: what prints the message
// escapes control characters and bytes that are no UTF-8 (\x1b, \xe8), as it
// does the file's name. Escaped here as well, the command line printed "\\x1b".
std::string quote(const Token& t) {
  if (t.at_end()) return "end of file";
  return "\"" + quoted_excerpt(std::string(t.text.substr(0, 41)), 40) + "\"";
}

std::string fmt(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

class NffParser {
 public:
  NffParser(std::string_view text, const std::string& name) : lex_(text), name_(name), empty_(text.empty()) {}

  Scene parse() {
    bool any_entity = false;
    for (Token t = lex_.next(); !t.at_end(); t = lex_.next()) {
      last_line_ = t.line;
      any_entity = true;
      entity(t);
    }
    // Said of the file, not of its line 1: a file that holds no scene at all
    // is most often the wrong file or one not yet written.
    if (!any_entity)
      throw InputError(name_ + (empty_ ? ": the file is empty" : ": the file holds only comments and blank lines") +
                       "; a scene needs a 'v' block (viewpoint) at least");
    if (view_line_ == 0) fail(last_line_, "expected a 'v' block (viewpoint) before end of file");
    if (dropped_warnings_ > 0)
      scene_.warnings.push_back(name_ + ": " + std::to_string(dropped_warnings_) +
                                " more warnings like these were not listed");
    return std::move(scene_);
  }

 private:
  void entity(const Token& t) {
    const std::string_view k = t.text;
    if (k == "b") background(t);
    else if (k == "v") view(t);
    else if (k == "l") light(t);
    else if (k == "f") material(t);
    else if (k == "c") cone(t);
    else if (k == "s") sphere(t);
    else if (k == "p") polygon(t, false);
    else if (k == "pp") polygon(t, true);
    else fail(t.line, unknown_keyword(t));
  }

  // A number where a keyword belongs is most often one number too many for
  // the entry before it (a fourth vertex after `p 3`, a colour on the line
  // after an `l`): said so, not as a keyword "0".
  static std::string unknown_keyword(const Token& t) {
    double number = 0;
    if (parse_double(t.text, number) != NumberKind::not_a_number)
      return "a number, " + quote(t) + ", where a keyword belongs (b, v, l, f, c, s, p or pp): more numbers than "
             "the entry before it takes?";
    return "unknown keyword " + quote(t) + " (expected b, v, l, f, c, s, p or pp)";
  }

  [[noreturn]] void fail(int line, const std::string& message) const {
    throw InputError(name_ + ":" + std::to_string(line) + ": " + message);
  }

  void warn(int line, const std::string& message) {
    if (scene_.warnings.size() < kMaxListedWarnings)
      scene_.warnings.push_back(name_ + ":" + std::to_string(line) + ": " + message);
    else
      ++dropped_warnings_;
  }

  // Reads `count` numbers into out[0..count); `where` describes them for the
  // message ("after 's'") and is only called on error. A missing number at end
  // of file is reported on the entity's line, a bad token on its own line.
  template <class Where>
  void read_numbers(double* out, int count, int entity_line, Where where) {
    for (int i = 0; i < count; ++i) {
      const Token t = lex_.next();
      const NumberKind kind = t.at_end() ? NumberKind::not_a_number : parse_double(t.text, out[i]);
      const int line = t.at_end() ? entity_line : t.line;
      if (kind == NumberKind::ok && std::abs(out[i]) > kMaxSceneMagnitude)
        fail(line, "number " + quote(t) + " " + where() + " is beyond +-" + fmt(kMaxSceneMagnitude) +
                       " (rays would leave the tracer's valid range)");
      if (kind == NumberKind::ok) continue;
      if (kind == NumberKind::not_finite)
        fail(line, std::string("expected a finite number ") + where() + ", found " + quote(t));
      fail(line, "expected " + std::to_string(count) + (count == 1 ? " number " : " numbers ") +
                     where() + ", found " + quote(t));
    }
  }

  Vec3 read_vec3(int entity_line, const char* where) {
    Vec3 v;
    read_numbers(&v.x, 3, entity_line, [where] { return where; });
    return v;
  }

  // The `v` block: six keyword lines in fixed order.
  void view(const Token& v) {
    if (view_line_ != 0)
      fail(v.line, "second 'v' block (the view is already set on line " + std::to_string(view_line_) + ")");
    view_line_ = v.line;
    Camera& cam = scene_.camera;
    expect_keyword("from", v.line);
    cam.from = read_vec3(v.line, "after 'from'");
    const int at_line = expect_keyword("at", v.line);
    cam.at = read_vec3(at_line, "after 'at'");
    const int up_line = expect_keyword("up", v.line);
    cam.up = read_vec3(up_line, "after 'up'");
    const int angle_line = expect_keyword("angle", v.line);
    read_numbers(&cam.angle_deg, 1, angle_line, [] { return "after 'angle'"; });
    const int hither_line = expect_keyword("hither", v.line);
    read_numbers(&cam.hither, 1, hither_line, [] { return "after 'hither'"; });
    const int res_line = expect_keyword("resolution", v.line);
    cam.width = read_resolution(res_line);
    cam.height = read_resolution(res_line);

    if (cam.from == cam.at) fail(at_line, "'from' and 'at' must differ");
    // Lengths below ~1e-154 square to 0: such a direction cannot be normalised,
    // and was blamed on 'up' as parallel to it.
    if (length(cam.at - cam.from) == 0)
      fail(at_line, "'from' and 'at' are too close together to give a viewing direction");
    const Vec3 dir = normalize(cam.at - cam.from);
    if (cam.up == Vec3{}) fail(up_line, "'up' must not be zero");
    if (length(cam.up) == 0) fail(up_line, "'up' is too short to give a direction");
    if (length(cross(dir, normalize(cam.up))) < 1e-9)
      fail(up_line, "'up' must not be parallel to the viewing direction");
    if (!(cam.angle_deg > 0 && cam.angle_deg < 180))
      fail(angle_line, "angle must be in (0, 180) degrees, found " + fmt(cam.angle_deg));
    if (cam.hither < 0) fail(hither_line, "hither must be >= 0, found " + fmt(cam.hither));
  }

  int expect_keyword(const char* keyword, int v_line) {
    const Token t = lex_.next();
    if (t.text != keyword)
      fail(t.at_end() ? v_line : t.line,
           std::string("expected \"") + keyword + "\" in the 'v' block, found " + quote(t));
    return t.line;
  }

  int read_resolution(int line) {
    const Token t = lex_.next();
    int value = 0;
    if (t.at_end() || !parse_int(t.text, value))
      fail(t.at_end() ? line : t.line, "expected 2 integers after 'resolution', found " + quote(t));
    if (value < 1 || value > kMaxResolution)
      fail(t.line, "resolution must be between 1 and " + std::to_string(kMaxResolution) +
                       ", found " + std::to_string(value));
    return value;
  }

  // `l X Y Z [R G B]`: the colour is there when the next token on the same
  // line is a number (the SPD never writes one).
  void light(const Token& l) {
    Light light;
    light.position = read_vec3(l.line, "after 'l'");
    double probe = 0;
    const std::string_view next = lex_.peek_on_line();
    if (!next.empty() && parse_double(next, probe) != NumberKind::not_a_number) {
      light.color = read_vec3(l.line, "for the colour of 'l'");
      // Brighter than 1 is a brighter light; below 0, light that darkens.
      const double rgb[] = {light.color.x, light.color.y, light.color.z};
      for (int i = 0; i < 3; ++i)
        if (!(rgb[i] >= 0))
          fail(l.line, std::string("light colour ") + "RGB"[i] + " must be >= 0, found " + fmt(rgb[i]));
    }
    scene_.lights.push_back(light);
  }

  void check_fraction(int line, const std::string& name, double value) {
    if (!(value >= 0 && value <= 1)) fail(line, name + " must be between 0 and 1, found " + fmt(value));
  }

  // The NFF document: "A color is simply RGB with values between 0 and 1".
  void background(const Token& b) {
    read_numbers(&scene_.background.x, 3, b.line, [] { return "after 'b'"; });
    const Vec3& c = scene_.background;
    check_fraction(b.line, "background R", c.x);
    check_fraction(b.line, "background G", c.y);
    check_fraction(b.line, "background B", c.z);
  }

  void material(const Token& f) {
    double n[8];
    read_numbers(n, 8, f.line, [] { return "after 'f' (R G B Kd Ks Shine T ior)"; });
    Material m;
    m.color = {n[0], n[1], n[2]};
    m.kd = n[3];
    m.ks = n[4];
    m.shine = n[5];
    m.transmittance = n[6];
    m.ior = n[7];
    // The NFF document: "RGB is in terms of 0.0 to 1.0", T is the fraction
    // of the transmitted ray's contribution, and "usually" Kd and Ks are in
    // [0, 1] -- not required, so only a negative one is refused. Negative
    // values shaded with negative light (a mirror that subtracts).
    for (int i = 0; i < 3; ++i) check_fraction(f.line, std::string(1, "RGB"[i]), n[i]);
    if (!(m.kd >= 0)) fail(f.line, "Kd must be >= 0, found " + fmt(m.kd));
    if (!(m.ks >= 0)) fail(f.line, "Ks must be >= 0, found " + fmt(m.ks));
    check_fraction(f.line, "T", m.transmittance);
    if (m.shine < 0) fail(f.line, "Shine must be >= 0, found " + fmt(m.shine));
    if (m.transmittance > 0 && m.ior <= 0)
      fail(f.line, "ior must be > 0 for a transmitting surface, found " + fmt(m.ior));
    scene_.materials.push_back(m);
    current_material_ = static_cast<int64_t>(scene_.materials.size() - 1);
  }

  // Primitives before the first `f` use a default white Kd 1 material: the
  // NFF document leaves this open, and it keeps such files renderable.
  uint32_t material_index() {
    if (current_material_ < 0) {
      scene_.materials.push_back(Material{});
      current_material_ = static_cast<int64_t>(scene_.materials.size() - 1);
    }
    return static_cast<uint32_t>(current_material_);
  }

  void sphere(const Token& s) {
    double n[4];
    read_numbers(n, 4, s.line, [] { return "after 's' (x y z radius)"; });
    if (n[3] < 0)
      fail(s.line, "negative sphere radius " + fmt(n[3]) + " (inside-visible spheres are not supported)");
    if (n[3] == 0) return warn(s.line, "skipped sphere with zero radius");
    scene_.spheres.push_back({{n[0], n[1], n[2]}, n[3], material_index()});
  }

  void cone(const Token& c) {
    double n[8];
    read_numbers(n, 8, c.line, [] { return "after 'c' (base x y z r, apex x y z r)"; });
    Cone cone{{n[0], n[1], n[2]}, n[3], {n[4], n[5], n[6]}, n[7], 0};
    if (cone.base_radius < 0 || cone.apex_radius < 0)
      fail(c.line, "negative cone radius (inside-visible cones are not supported)");
    if (cone.base == cone.apex) return warn(c.line, "skipped cone with base == apex");
    if (cone.base_radius == 0 && cone.apex_radius == 0)
      return warn(c.line, "skipped cone with both radii 0");
    cone.material = material_index();
    scene_.cones.push_back(cone);
  }

  void polygon(const Token& p, bool patch) {
    const char* kw = patch ? "pp" : "p";
    const Token count_token = lex_.next();
    int count = 0;
    if (count_token.at_end() || !parse_int(count_token.text, count))
      fail(count_token.at_end() ? p.line : count_token.line,
           std::string("expected a vertex count after '") + kw + "', found " + quote(count_token));
    if (count < 3)
      fail(count_token.line, std::string("expected a vertex count >= 3 after '") + kw + "', found " +
                                 std::to_string(count));
    if (count > kMaxPolygonVertices)
      fail(count_token.line, std::string("'") + kw + " " + std::to_string(count) + "': at most " +
                                 std::to_string(kMaxPolygonVertices) +
                                 " vertices to a polygon (split it into several)");
    read_vertices(p.line, kw, count, patch);
    finish_polygon(p.line, patch);
  }

  // Appends the raw vertices (and normals) to poly_vertices_/poly_normals_.
  void read_vertices(int line, const char* kw, int count, bool patch) {
    poly_vertices_.clear();
    poly_normals_.clear();
    const int per_vertex = patch ? 6 : 3;
    for (int i = 0; i < count; ++i) {
      double n[6];
      read_numbers(n, per_vertex, line, [&] {
        return "for vertex " + std::to_string(i + 1) + " of '" + kw + " " + std::to_string(count) + "'";
      });
      poly_vertices_.push_back({n[0], n[1], n[2]});
      if (patch) poly_normals_.push_back({n[3], n[4], n[5]});
    }
  }

  // Removes repeated consecutive vertices, skips zero-area polygons, repairs
  // zero normals, and appends the result to the scene.
  void finish_polygon(int line, bool patch) {
    size_t kept = 0;
    const size_t n = poly_vertices_.size();
    for (size_t i = 0; i < n; ++i) {
      if (kept > 0 && poly_vertices_[i] == poly_vertices_[kept - 1]) continue;
      poly_vertices_[kept] = poly_vertices_[i];
      if (patch) poly_normals_[kept] = poly_normals_[i];
      ++kept;
    }
    while (kept > 1 && poly_vertices_[kept - 1] == poly_vertices_[0]) --kept;
    if (kept < n) warn(line, "removed " + std::to_string(n - kept) + " repeated polygon vertices");
    const uint32_t count = static_cast<uint32_t>(kept);
    // Newell's area: a bow tie's two loops cancel, as collinear vertices have none.
    if (polygon_is_degenerate(poly_vertices_.data(), count))
      return warn(line, "skipped polygon with zero area (vertices in a line, or crossing edges whose loops cancel)");

    Polygon poly;
    poly.first = static_cast<uint32_t>(scene_.vertices.size());
    poly.count = count;
    poly.has_normals = patch;
    poly.material = material_index();
    scene_.polygons.push_back(poly);
    scene_.vertices.insert(scene_.vertices.end(), poly_vertices_.begin(), poly_vertices_.begin() + count);
    if (patch && scene_.normals.empty()) scene_.normals.resize(poly.first);
    if (!patch) {
      if (!scene_.normals.empty()) scene_.normals.resize(scene_.vertices.size());
      return;
    }
    const Vec3 face = normalize(polygon_normal(poly_vertices_.data(), count));
    for (uint32_t i = 0; i < count; ++i) {
      Vec3 normal = normalize(poly_normals_[i]);
      if (length(normal) == 0) {
        warn(line, "zero-length normal of vertex " + std::to_string(i + 1) + " replaced by the face normal");
        normal = face;
      }
      scene_.normals.push_back(normal);
    }
  }

  Lexer lex_;
  const std::string& name_;
  bool empty_;  // the text has no bytes at all
  Scene scene_;
  int view_line_ = 0;  // line of the `v` keyword, 0 until seen
  int last_line_ = 1;
  int64_t current_material_ = -1;
  size_t dropped_warnings_ = 0;
  std::vector<Vec3> poly_vertices_, poly_normals_;  // scratch for one polygon
};

}  // namespace

Scene parse_nff(std::string_view text, const std::string& name) {
  return NffParser(text, name).parse();
}

std::string read_nff_text(const std::string& path) {
  return read_text_file_within(path, kMaxSceneBytes, std::to_string(kMaxSceneBytes >> 20) + " MiB scene limit");
}

Scene read_nff_file(const std::string& path) {
  return parse_nff(read_nff_text(path), path);
}

}  // namespace rayfarm
