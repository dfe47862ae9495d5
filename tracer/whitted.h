// Whitted-style shading with the SPD conventions (spd/README.md sections 2, 7):
// an ambient term on every surface, Phong diffuse + highlight per visible light
// (intensity 1/sqrt(#lights), same for ambient), a mirror ray weighted by Ks,
// a Snell refraction ray weighted by T (total internal reflection adds T to the
// mirror ray), depth limit with the eye ray at depth 1, background on a miss.
// Shadows are opaque (classic SPD/Haines): one shadow ray per light in front of
// the surface, blocked by any primitive, transmitters included.
//
// A batch of eye rays (neighbouring pixels' samples) is traced as a wavefront: each
// depth of the ray tree goes to Embree in packets of up to 16 coherent rays,
// and every shadow ray of that depth too. Whitted shading is linear in its
// child rays, so each ray carries the product of the Ks/T weights above it and
// adds its local shading to its sample directly. The integrator is instantiated
// per EffectSet, so a scene that cannot refract never evaluates a refraction
// branch. With a cutoff (render_settings.h) a mirror or refraction ray is not
// spawned when its weight times contribution_bound() falls below it.
#pragma once

#include <utility>
#include <vector>

#include "tracer/embree_scene.h"
#include "tracer/hit_frame.h"
#include "tracer/phong.h"
#include "tracer/ray_stats.h"
#include "tracer/render_settings.h"
#include "tracer/scene.h"

namespace rayfarm {

// What the scene's primitives can cause: lights -> shadows, a used material with
// Ks > 0 or T > 0 -> reflection, T > 0 -> refraction, a `pp` patch -> smooth
// normals. Materials that no primitive uses do not count.
EffectSet derive_effects(const Scene& scene);

class WhittedIntegrator {
 public:
  // Shading conventions. NFF has no ambient coefficient; the SPD library's
  // internal default is 0.2, applied here to Kd * colour.
  static constexpr double kAmbient = 0.2;

  WhittedIntegrator(const Scene& scene, const EmbreeScene& embree, const RenderSettings& settings);

  // Colours of `count` eye rays from the camera (directions need not be unit),
  // traced together. A ray's colour depends only on the rays passed with it.
  void trace_eye_rays(const Vec3* dirs, int count, Vec3* colors, RayStats& stats) const {
    (this->*trace_)(dirs, count, colors, stats);
  }
  Vec3 trace_eye(const Vec3& dir, RayStats& stats) const {
    Vec3 c;
    trace_eye_rays(&dir, 1, &c, stats);
    return c;
  }

  // The colour trace_eye_rays() gives an eye ray that meets nothing, to the
  // bit: every eye ray's colour starts at zero, and a miss adds the
  // background at the eye ray's weight, 1.
  Vec3 eye_miss_color() const {
    Vec3 c{};
    c += background_ * 1.0;
    return c;
  }

  const EffectSet& effects() const { return effects_; }

  // The most one ray can add to its sample before its weight: the brightest
  // channel of the background or of any surface's ambient + every light's
  // diffuse and highlight at full strength. Independent of where lights are.
  double contribution_bound() const { return contribution_bound_; }

  struct Workspace;  // per-thread ray levels and scratch (whitted.cpp)

  struct LocalLight {
    Vec3 position;   // camera-relative
    Vec3 intensity;  // colour / sqrt(#lights)
  };
  struct Surface {
    Vec3 color;    // R G B
    Vec3 ambient;  // kAmbient * ambient intensity * Kd * colour
    double kd, ks, shine, transmittance, ior;
  };
  // Everything shading needs about the hits of one packet of a level's rays,
  // lane by lane where the hit-frame kernel leaves them (no copy): their
  // frames (hit_frame.h), materials, shading normals and the rays they end.
  // A level's point j is lane j % kLanes of its packet j / kLanes.
  struct PacketPoints {
    static constexpr int kLanes = HitLanes::kLanes;
    HitLanes frames;
    alignas(64) double ns[3][kLanes];  // with `pp` patches: see shading_normals()
    const Surface* m[kLanes];
    int owner[kLanes];  // the level's ray that hit
    int count = 0;      // lanes [0, count) hold hits
    uint32_t departs = 0;  // lanes whose hit's outside rays leave (EmbreeScene::Departure)
    ChildLanes children;  // their child rays, where spawns_children
    bool spawns_children = false;  // a lane's material has Ks > 0 or T > 0
  };

 private:
  static constexpr unsigned kShadows = 1, kReflection = 2, kRefraction = 4, kSmooth = 8;

  template <unsigned F>
  void set_shading_normals(const TraceHit* hits, PacketPoints& points) const;
  // The points' unit shading normals, on the side of nf: their nf, or with
  // `pp` patches their own (set_shading_normals()).
  const double (&shading_normals(const PacketPoints& points) const)[3][PacketPoints::kLanes] {
    return effects_.smooth_normals ? points.ns : points.frames.nf;
  }
  static Vec3 direct_light(const Surface& m, const PhongTerms& terms, const LocalLight& light);
  void occluded(Workspace& ws, uint32_t light, int first, int count, EmbreeScene::Origins found_by,
                bool* blocked) const;
  void add_direct_light(Workspace& ws, const LocalLight& light, const int* shadow_of, const bool* blocked,
                        int count, Vec3* colors) const;
  // Whether a child ray of this weight passes the cutoff (always, at cutoff 0).
  bool worth_spawning(double weight) const { return !(weight * contribution_bound_ < cutoff_); }
  template <unsigned F>
  void trace(const Vec3* dirs, int count, Vec3* colors, RayStats& stats) const;
  template <unsigned F>
  void intersect_level(Workspace& ws, Vec3* colors, EmbreeScene::Origins origins) const;
  template <unsigned F>
  void add_packet_hits(Workspace& ws, PacketPoints& points, int first, int count, Vec3* colors) const;
  // `found_by`: how the level's rays started (EmbreeScene::walks_alone()).
  void light_level(Workspace& ws, Vec3* colors, RayStats& stats, EmbreeScene::Origins found_by) const;
  template <unsigned F>
  void spawn_level(Workspace& ws, RayStats& stats) const;
  template <unsigned F>
  void find_child_rays(PacketPoints& points) const;

  using TraceFn = void (WhittedIntegrator::*)(const Vec3*, int, Vec3*, RayStats&) const;
  template <unsigned... F>
  static TraceFn pick(unsigned flags, std::integer_sequence<unsigned, F...>);

  const EmbreeScene& embree_;
  EffectSet effects_;
  Vec3 background_;
  int max_depth_;
  double cutoff_;              // settings.cutoff
  double contribution_bound_;  // contribution_bound()
  std::vector<LocalLight> lights_;
  std::vector<Surface> surfaces_;
  TraceFn trace_ = nullptr;
};

}  // namespace rayfarm
