// Hard-case scenes for the accuracy tests, written as NFF text so that they go
// through the same reader as user scenes. NffText applies one similarity
// transform (uniform scale, then translation) to every position and length, so
// one scene can be rendered at 1e-3 or 1e6 units and compared with itself.
// Also small helpers: render a scene to float RGB (asserting that no sample
// was NaN or Inf), a tessellated sphere.
#pragma once

#include <doctest/doctest.h>

#include <cmath>
#include <cstdio>
#include <deque>
#include <string>
#include <vector>

#include "tracer/nff_reader.h"
#include "tracer/ray_stats.h"
#include "tracer/render_settings.h"
#include "tracer/renderer.h"
#include "tracer/scene.h"
#include "tracer/vec3.h"

namespace rayfarm::test {

class NffText {
 public:
  explicit NffText(double scale = 1, Vec3 offset = {}) : scale_(scale), offset_(offset) {}

  NffText& background(Vec3 c) { return line("b %s", vec(c, false)); }
  NffText& view(Vec3 from, Vec3 at, Vec3 up, double angle, int res, double hither = 1e-3) {
    line("v");
    line("from %s", vec(from));
    line("at %s", vec(at));
    line("up %s", vec(up, false));
    line("angle %s", num(angle));
    line("hither %s", num(hither * scale_));
    return line("resolution %d %d", res, res);
  }
  NffText& light(Vec3 p) { return line("l %s", vec(p)); }
  // NFF `f R G B Kd Ks Shine T ior`.
  NffText& fill(Vec3 c, double kd, double ks, double shine, double t, double ior) {
    return line("f %s %s %s %s %s %s", vec(c, false), num(kd), num(ks), num(shine), num(t), num(ior));
  }
  NffText& sphere(Vec3 c, double r) { return line("s %s %s", vec(c), num(r * scale_)); }
  NffText& cone(Vec3 base, double rb, Vec3 apex, double ra) {
    return line("c %s %s %s %s", vec(base), num(rb * scale_), vec(apex), num(ra * scale_));
  }
  NffText& polygon(const std::vector<Vec3>& vs) {
    line("p %d", static_cast<int>(vs.size()));
    for (const Vec3& v : vs) line("%s", vec(v));
    return *this;
  }
  NffText& patch(const std::vector<Vec3>& vs, const std::vector<Vec3>& ns) {
    line("pp %d", static_cast<int>(vs.size()));
    for (size_t i = 0; i < vs.size(); ++i) line("%s %s", vec(vs[i]), vec(ns[i], false));
    return *this;
  }
  NffText& raw(const std::string& text) {
    text_ += text;
    text_ += "\n";
    return *this;
  }

  const std::string& str() const { return text_; }
  Scene parse(const std::string& name = "test.nff") const { return parse_nff(text_, name); }

 private:
  // Full double precision: a scene moved by 1e6 must not lose its detail in
  // the text (the SPD's %g would keep only 6 digits).
  const char* num(double v) {
    buffers_.emplace_back();
    std::snprintf(buffers_.back().data, sizeof buffers_.back().data, "%.17g", v);
    return buffers_.back().data;
  }
  const char* vec(Vec3 p, bool transform = true) {
    if (transform) p = p * scale_ + offset_;
    buffers_.emplace_back();
    std::snprintf(buffers_.back().data, sizeof buffers_.back().data, "%.17g %.17g %.17g", p.x, p.y, p.z);
    return buffers_.back().data;
  }
  template <class... A>
  NffText& line(const char* fmt, A... args) {
    char buf[1024];  // room for six 96-byte fields
    std::snprintf(buf, sizeof buf, fmt, args...);
    text_ += buf;
    text_ += "\n";
    buffers_.clear();
    return *this;
  }
  NffText& line(const char* s) { return raw(s); }

  struct Buffer {
    char data[96];
  };
  double scale_;
  Vec3 offset_;
  std::string text_;
  std::deque<Buffer> buffers_;  // stable addresses while a line is formatted
};

// Renders a whole image; stats when asked. Every sample the integrator
// returns must be finite: the Renderer stores NaN/Inf as 0, so the raw count in
// the stats is checked here, for every hard case rendered through this.
inline std::vector<float> render_image(const Scene& scene, RenderSettings settings,
                                       RayStats* stats = nullptr) {
  const Renderer renderer(scene, settings);
  std::vector<float> rgb;
  RayStats own;
  renderer.render_rows(0, settings.height, rgb, &own);
  CHECK_MESSAGE(own.non_finite == 0, own.non_finite << " of " << own.eye << " samples were NaN or Inf");
  if (stats) *stats += own;
  return rgb;
}

inline RenderSettings small_settings(int size, int spp, int threads = 2) {
  RenderSettings s;
  s.width = s.height = size;
  s.spp = spp;
  s.threads = threads;
  return s;
}

// A closed UV sphere of triangles sharing vertices exactly (every edge is used
// by two triangles with bit-identical endpoints): `rings` latitude bands and
// `segments` longitude segments, wound counter-clockwise seen from outside.
inline std::vector<std::vector<Vec3>> tessellated_sphere(Vec3 center, double r, int rings, int segments) {
  const double pi = 3.14159265358979323846;
  std::vector<std::vector<Vec3>> grid(rings + 1, std::vector<Vec3>(segments));
  for (int i = 0; i <= rings; ++i) {
    const double theta = pi * i / rings;  // from the north pole
    for (int j = 0; j < segments; ++j) {
      const double phi = 2 * pi * j / segments;
      grid[i][j] = center + r * Vec3{std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi),
                                     std::cos(theta)};
      // Exact poles: sin(pi) is 1.2e-16, not 0, and would split the south pole.
      if (i == 0 || i == rings) grid[i][j] = center + Vec3{0, 0, i == 0 ? r : -r};
    }
  }
  std::vector<std::vector<Vec3>> tris;
  for (int i = 0; i < rings; ++i) {
    for (int j = 0; j < segments; ++j) {
      const int jn = (j + 1) % segments;
      const Vec3 a = grid[i][j], b = grid[i + 1][j], c = grid[i + 1][jn], d = grid[i][jn];
      if (i != 0) tris.push_back({a, b, d});               // the poles' bands are single triangles
      if (i != rings - 1) tris.push_back({b, c, d});
    }
  }
  return tris;
}

}  // namespace rayfarm::test
