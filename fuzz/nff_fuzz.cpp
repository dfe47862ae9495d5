// libFuzzer target: the NFF reader (tracer/nff_reader.h) on arbitrary bytes.
// It must return a Scene or throw InputError "fuzz.nff:LINE: ..."; a returned
// Scene holds only finite numbers and in-range indices, as the reader promises
// (nothing downstream may see a NaN or index past a vector).
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "fuzz/fuzz_oracle.h"
#include "tracer/nff_reader.h"

using namespace rayfarm;

namespace {

void check_scene(const Scene& s) {
  const auto finite = [](const Vec3& v, const char* what) {
    if (!is_finite(v)) fuzz::fail(std::string("non-finite ") + what);
  };
  finite(s.background, "background");
  finite(s.camera.from, "camera.from");
  finite(s.camera.at, "camera.at");
  finite(s.camera.up, "camera.up");
  if (s.camera.width < 1 || s.camera.height < 1) fuzz::fail("empty resolution");
  for (const Light& l : s.lights) finite(l.position, "light");
  for (const Sphere& sp : s.spheres) {
    finite(sp.center, "sphere");
    if (sp.material >= s.materials.size()) fuzz::fail("sphere material out of range");
  }
  for (const Cone& c : s.cones) {
    finite(c.base, "cone base");
    finite(c.apex, "cone apex");
    if (c.material >= s.materials.size()) fuzz::fail("cone material out of range");
  }
  for (const Vec3& v : s.vertices) finite(v, "vertex");
  for (const Polygon& p : s.polygons) {
    if (p.count < 3 || size_t{p.first} + p.count > s.vertices.size()) fuzz::fail("polygon vertices out of range");
    if (p.has_normals && size_t{p.first} + p.count > s.normals.size()) fuzz::fail("polygon normals out of range");
    if (p.material >= s.materials.size()) fuzz::fail("polygon material out of range");
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  fuzz::expect_clean_error("fuzz.nff:", [&] { check_scene(parse_nff(text, "fuzz.nff")); });
  return 0;
}
