// Scene: the renderer-independent description of what an NFF file says.
// The NFF reader fills it, the SPD generators' output parses into it, and the
// Embree scene (embree_scene.h) is built from it. Plain data, no behaviour beyond
// a few queries; primitives keep the index of the `f` material in force.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "tracer/vec3.h"

namespace rayfarm {

// The NFF `v` block. `angle` is the full field of view in degrees between the
// centres of the outermost pixel rows/columns (NFF definition).
struct Camera {
  Vec3 from{0, 0, 1};
  Vec3 at{0, 0, 0};
  Vec3 up{0, 1, 0};
  double angle_deg = 45;
  double hither = 1e-3;
  int width = 512;
  int height = 512;
};

struct Light {
  Vec3 position;
  Vec3 color{1, 1, 1};
};

// NFF `f R G B Kd Ks Shine T ior`.
struct Material {
  Vec3 color{1, 1, 1};
  double kd = 1;
  double ks = 0;
  double shine = 0;
  double transmittance = 0;
  double ior = 1;
};

struct Sphere {
  Vec3 center;
  double radius = 0;
  uint32_t material = 0;
};

// NFF `c`: an open cone or cylinder (no end caps) between two circles.
struct Cone {
  Vec3 base;
  double base_radius = 0;
  Vec3 apex;
  double apex_radius = 0;
  uint32_t material = 0;
};

// NFF `p` and `pp`: a planar, possibly concave polygon. Its vertices are the
// range [first, first + count) of Scene::vertices; for a `pp` patch the same
// range of Scene::normals holds the per-vertex normals.
struct Polygon {
  uint32_t first = 0;
  uint32_t count = 0;
  bool has_normals = false;
  uint32_t material = 0;
};

struct Scene {
  Vec3 background{0, 0, 0};
  Camera camera;
  std::vector<Light> lights;
  std::vector<Material> materials;
  std::vector<Sphere> spheres;
  std::vector<Cone> cones;
  std::vector<Polygon> polygons;
  std::vector<Vec3> vertices;  // polygon vertices, see Polygon
  // Per-vertex normals of `pp` patches, indexed like `vertices`: empty while the
  // scene has no patch, else as long as `vertices` (zero for plain `p` vertices).
  std::vector<Vec3> normals;
  std::vector<std::string> warnings;  // "file:line: ..." for input that was skipped

  size_t primitive_count() const { return spheres.size() + cones.size() + polygons.size(); }
};

}  // namespace rayfarm
