// NFF text output with the SPD library's exact layout and "%g" numbers.

#include "spd/nff_writer.h"

#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace rayfarm::spd {
namespace {
// Hand the buffer to the stream in chunks of about this size: large enough that
// stream overhead vanishes, small enough that memory stays flat.
constexpr std::size_t kFlushBytes = 1 << 16;
}  // namespace

NffWriter::NffWriter(std::ostream& out) : out_(out) { buf_.reserve(kFlushBytes + 4096); }

NffWriter::~NffWriter() {
  try {
    flush();
  } catch (...) {
    // A destructor must not throw; callers that care call flush() themselves.
  }
}

void NffWriter::flush() {
  if (!buf_.empty()) {
    out_.write(buf_.data(), static_cast<std::streamsize>(buf_.size()));
    buf_.clear();
  }
  out_.flush();
  if (!out_) throw std::runtime_error("failed to write NFF output");
}

void NffWriter::first_number(double v) {
  // "%g" is the format the reference files are written in (6 significant
  // digits, shortest of %e/%f, trailing zeros dropped, "-0" kept).
  char tmp[32];
  const int n = std::snprintf(tmp, sizeof tmp, "%g", v);
  buf_.append(tmp, static_cast<std::size_t>(n));
}

void NffWriter::number(double v) {
  buf_.push_back(' ');
  first_number(v);
}

void NffWriter::integer(int v) {
  char tmp[16];
  const int n = std::snprintf(tmp, sizeof tmp, "%d", v);
  buf_.append(tmp, static_cast<std::size_t>(n));
}

void NffWriter::text(const char* s) { buf_.append(s); }

void NffWriter::end_line() {
  buf_.push_back('\n');
  if (buf_.size() >= kFlushBytes) {
    out_.write(buf_.data(), static_cast<std::streamsize>(buf_.size()));
    buf_.clear();
    if (!out_) throw std::runtime_error("failed to write NFF output");
  }
}

void NffWriter::comment(const std::string& line) {
  text("# ");
  buf_.append(line);
  end_line();
}

void NffWriter::background(double r, double g, double b) {
  text("b");
  numbers(r, g, b);
  end_line();
}

void NffWriter::viewpoint(const View& v) {
  text("v");
  end_line();
  text("from");
  numbers(v.from.x, v.from.y, v.from.z);
  end_line();
  text("at");
  numbers(v.at.x, v.at.y, v.at.z);
  end_line();
  text("up");
  numbers(v.up.x, v.up.y, v.up.z);
  end_line();
  text("angle");
  number(v.angle);
  end_line();
  text("hither");
  number(v.hither);
  end_line();
  text("resolution ");
  integer(v.resx);
  text(" ");
  integer(v.resy);
  end_line();
}

void NffWriter::light(const Coord& p) {
  text("l");
  numbers(p.x, p.y, p.z);
  end_line();
}

double NffWriter::phong_exponent(double half_angle_degrees) {
  const double radians = kPi * half_angle_degrees / 180.0;
  if (radians <= 0.0) return 100000.0;
  if (radians >= kPi / 2.0) return 1.0;
  return std::log(0.5) / std::log(std::cos(radians));
}

void NffWriter::surface(const Surface& s) {
  text("f");
  numbers(s.r, s.g, s.b);
  numbers(s.kd, s.ks, phong_exponent(s.phong_angle));
  numbers(s.kt, s.ior);
  end_line();
}

void NffWriter::sphere(const Coord& c) {
  text("s");
  numbers(c.x, c.y, c.z, c.w);
  end_line();
}

void NffWriter::cone(const Coord& base, const Coord& apex) {
  text("c");
  numbers(base.x, base.y, base.z, base.w);
  numbers(apex.x, apex.y, apex.z, apex.w);
  end_line();
}

void NffWriter::polygon(const Coord* vertices, int count) {
  text("p ");
  integer(count);
  end_line();
  for (int i = 0; i < count; ++i) {
    first_number(vertices[i].x);
    numbers(vertices[i].y, vertices[i].z);
    end_line();
  }
}

void NffWriter::patch(const Coord* vertices, const Coord* normals, int count) {
  text("pp ");
  integer(count);
  end_line();
  for (int i = 0; i < count; ++i) {
    first_number(vertices[i].x);
    numbers(vertices[i].y, vertices[i].z);
    numbers(normals[i].x, normals[i].y, normals[i].z);
    end_line();
  }
}

}  // namespace rayfarm::spd
