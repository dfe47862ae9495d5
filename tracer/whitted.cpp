// Whitted shading as a per-batch wavefront; one template per effect
// combination (see whitted.h).
#include "tracer/whitted.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstring>

#include "tracer/child_rays.h"
#include "tracer/phong.h"
#include "tracer/start_shadow_caches.h"

namespace rayfarm {

EffectSet derive_effects(const Scene& scene) {
  std::vector<bool> used(scene.materials.size(), false);
  auto use = [&](uint32_t m) {
    if (m < used.size()) used[m] = true;
  };
  for (const Sphere& s : scene.spheres) use(s.material);
  for (const Cone& c : scene.cones) use(c.material);
  EffectSet effects;
  for (const Polygon& p : scene.polygons) {
    use(p.material);
    effects.smooth_normals |= p.has_normals;
  }
  if (scene.primitive_count() == 0) return effects;  // nothing to shade, nothing spawns
  effects.shadows = !scene.lights.empty();
  for (size_t m = 0; m < scene.materials.size(); ++m) {
    if (!used[m]) continue;
    const Material& mat = scene.materials[m];
    effects.reflection |= mat.ks > 0 || mat.transmittance > 0;
    effects.refraction |= mat.transmittance > 0;
  }
  return effects;
}

WhittedIntegrator::WhittedIntegrator(const Scene& scene, const EmbreeScene& embree, const RenderSettings& settings)
    : embree_(embree),
      effects_(derive_effects(scene)),
      background_(scene.background),
      max_depth_(settings.max_depth),
      cutoff_(settings.cutoff) {
  // Haines' SPD convention: each of N lights, and the ambient light, has
  // intensity 1/sqrt(N), so images keep their brightness as lights are added.
  const double intensity = 1.0 / std::sqrt(static_cast<double>(scene.lights.empty() ? 1 : scene.lights.size()));
  for (const Light& l : scene.lights) lights_.push_back({embree.to_local(l.position), l.color * intensity});
  for (const Material& m : scene.materials) {
    const Vec3 ambient = m.color * (kAmbient * intensity * m.kd);
    surfaces_.push_back({m.color, ambient, m.kd, m.ks, m.shine, m.transmittance, m.ior});
  }
  if (surfaces_.empty()) surfaces_.push_back({{1, 1, 1}, {kAmbient, kAmbient, kAmbient}, 1, 0, 0, 0, 1});
  contribution_bound_ = std::max({background_.x, background_.y, background_.z});
  for (const Surface& m : surfaces_) {
    Vec3 most = m.ambient;
    // direct_light() is at most (kd * colour + ks) * intensity: n.l <= 1, (r.v)^n <= 1.
    for (const LocalLight& l : lights_) most += (m.color * m.kd + Vec3{m.ks, m.ks, m.ks}) * l.intensity;
    contribution_bound_ = std::max({contribution_bound_, most.x, most.y, most.z});
  }
  const unsigned flags = (effects_.shadows ? kShadows : 0) | (effects_.reflection ? kReflection : 0) |
                         (effects_.refraction ? kRefraction : 0) | (effects_.smooth_normals ? kSmooth : 0);
  trace_ = pick(flags, std::make_integer_sequence<unsigned, 16>{});
}

template <unsigned... F>
WhittedIntegrator::TraceFn WhittedIntegrator::pick(unsigned flags, std::integer_sequence<unsigned, F...>) {
  static constexpr TraceFn table[] = {&WhittedIntegrator::trace<F>...};
  return table[flags];
}

namespace {

// One depth of the ray tree: each ray, the sample it adds to, its weight
// (the product of the Ks / T factors on its path from the eye), the
// primitive it departs (EmbreeScene::Departure) and the sphere it starts
// inside (EmbreeScene::intersect_packet()'s hint). The arrays
// only grow, and push() fills them in place: room is made once per level
// (make_room()), not checked four times per ray as push_back would.
struct RayLevel {
  std::vector<Vec3> orgs, dirs;
  std::vector<double> weights;
  std::vector<int> samples;
  std::vector<EmbreeScene::Departure> departures;
  std::vector<uint32_t> inside;
  size_t count = 0;

  size_t size() const { return count; }
  void clear() { count = 0; }
  // Room for `more` rays past the current ones.
  void make_room(size_t more) {
    if (count + more <= orgs.size()) return;
    orgs.resize(count + more);
    dirs.resize(count + more);
    weights.resize(count + more);
    samples.resize(count + more);
    departures.resize(count + more);
    inside.resize(count + more);
  }
  // An eye ray: its departure and sphere are never read (eye rays depart
  // nothing and are not said to start inside anything, see intersect_level()).
  void push(const Vec3& org, const Vec3& dir, double weight, int sample) {
    assert(count < orgs.size());  // make_room() first
    orgs[count] = org;
    dirs[count] = dir;
    weights[count] = weight;
    samples[count++] = sample;
  }
  void push(const Vec3& org, const Vec3& dir, double weight, int sample, const EmbreeScene::Departure& departure,
            uint32_t inside_sphere) {
    assert(count < departures.size());
    departures[count] = departure;
    inside[count] = inside_sphere;
    push(org, dir, weight, sample);
  }
};

}  // namespace

// Per-thread scratch, reused so the hot path allocates nothing once warm.
struct WhittedIntegrator::Workspace {
  RayLevel level, next;
  std::vector<TraceHit> hits;
  PhongLanes phong;  // one packet's lit hits, for the Phong kernel
  // The level's hits, packet by packet: points[0, packet_count). The vector
  // only grows, so filling it in place never re-initialises a packet's.
  std::vector<WhittedIntegrator::PacketPoints> points;
  size_t packet_count = 0, hit_count = 0;
  bool any_departs = false;  // whether any point departs (PacketPoints::departs)
  std::vector<Vec3> shadow_orgs, shadow_dirs;
  std::vector<int> shadow_of;  // shadow ray -> index into points
  std::vector<EmbreeScene::ShadowCache> shadow_cache;  // per light, for the current wavefront's rays
  StartShadowCaches start_caches;  // per primitive and light, for rays walked one by one
};

namespace {

WhittedIntegrator::Workspace& workspace() {
  thread_local WhittedIntegrator::Workspace w;
  return w;
}

constexpr int kPacket = EmbreeScene::kPacket;

using PacketPoints = WhittedIntegrator::PacketPoints;
static_assert(PacketPoints::kLanes == kPacket, "a packet's hits fill one PacketPoints");

// Whether point i's refraction is total internal reflection (never without
// refraction: the child-ray kernel leaves the flags 0).
inline bool total_internal(const PacketPoints& points, int i) { return (points.children.total_internal >> i) & 1; }

// What a ray that leaves point i of `points` (hit `hit`) away from the
// surface departs (PacketPoints::departs).
inline EmbreeScene::Departure departure(const EmbreeScene& embree, const PacketPoints& points, int i,
                                        const TraceHit& hit) {
  return (points.departs >> i) & 1 ? embree.departure_from(hit) : EmbreeScene::Departure{};
}

// The sphere a child ray of point i (hit `hit`) starts inside, if any: the
// refraction ray of a sphere entered, the mirror ray off one's inside.
inline uint32_t sphere_inside(const PacketPoints& points, int i, const TraceHit& hit, bool refracted) {
  const bool entered = (points.frames.entering >> i) & 1;
  return hit.geom == EmbreeScene::kSpheres && entered == refracted ? hit.prim : EmbreeScene::kNoSphere;
}

}  // namespace

// With `pp` patches, the shading normals on the side of nf: nf itself, or a
// patch's interpolated vertex normal; hits[owner] are the points' hits.
// (Without, the shading normal is nf: see shading_normals().)
template <unsigned F>
void WhittedIntegrator::set_shading_normals(const TraceHit* hits, PacketPoints& points) const {
  if constexpr ((F & kSmooth) != 0) {
    static_assert(sizeof points.ns == sizeof points.frames.nf);
    std::memcpy(points.ns, points.frames.nf, sizeof points.ns);
    for (int i = 0; i < points.count; ++i) {
      Vec3 vn;
      if (!embree_.vertex_normal(hits[points.owner[i]], vn)) continue;
      const Vec3 nf = lane_vec(points.frames.nf, i);
      vn = unit_or(vn, nf);
      if (dot(vn, nf) < 0) vn = -vn;
      points.ns[0][i] = vn.x, points.ns[1][i] = vn.y, points.ns[2][i] = vn.z;
    }
  }
}

// Phong diffuse + highlight of one unoccluded light in front of a surface.
Vec3 WhittedIntegrator::direct_light(const Surface& m, const PhongTerms& terms, const LocalLight& light) {
  Vec3 c = m.color * (m.kd * terms.n_dot_l);
  if (terms.highlit) c += Vec3{terms.highlight, terms.highlight, terms.highlight};
  return c * light.intensity;
}

template <unsigned F>
void WhittedIntegrator::trace(const Vec3* dirs, int count, Vec3* colors, RayStats& stats) const {
  Workspace& ws = workspace();
  ws.level.clear();
  ws.level.make_room(count);
  ws.shadow_cache.assign(lights_.size(), EmbreeScene::ShadowCache{});
  ws.start_caches.use_for(embree_, static_cast<uint32_t>(lights_.size()));
  for (int i = 0; i < count; ++i) {
    ws.level.push(Vec3{}, dirs[i], 1.0, i);
    colors[i] = Vec3{};
  }
  stats.eye += count;
  for (int depth = 1; ws.level.size() > 0; ++depth) {
    const auto origins = depth == 1 ? EmbreeScene::Origins::kOnePoint : EmbreeScene::Origins::kScattered;
    intersect_level<F>(ws, colors, origins);
    if (depth == 1) stats.eye_hit += ws.hit_count;
    if constexpr ((F & kShadows) != 0) light_level(ws, colors, stats, origins);
    ws.next.clear();
    if constexpr ((F & (kReflection | kRefraction)) != 0) {
      if (depth < max_depth_) spawn_level<F>(ws, stats);
    }
    std::swap(ws.level, ws.next);
  }
}

// Traces every ray of the level, which start at `origins`; misses add the
// background, hits their ambient term and become ws.points[0, ws.packet_count).
template <unsigned F>
void WhittedIntegrator::intersect_level(Workspace& ws, Vec3* colors, EmbreeScene::Origins origins) const {
  const RayLevel& level = ws.level;
  const int n = static_cast<int>(level.size());
  ws.hits.resize(n);
  ws.packet_count = (size_t(n) + kPacket - 1) / kPacket;
  if (ws.points.size() < ws.packet_count) ws.points.resize(ws.packet_count);
  ws.hit_count = 0;
  ws.any_departs = false;
  for (int b = 0; b < n; b += kPacket) {
    const int count = std::min(kPacket, n - b);
    // Eye rays (from one point) depart nothing.
    const bool from_eye = origins == EmbreeScene::Origins::kOnePoint;
    const EmbreeScene::Departure* departures = from_eye ? nullptr : &level.departures[b];
    const uint32_t* inside = from_eye ? nullptr : &level.inside[b];
    embree_.intersect_packet(&level.orgs[b], &level.dirs[b], count, &ws.hits[b], origins, departures, inside);
    PacketPoints& points = ws.points[b / kPacket];
    add_packet_hits<F>(ws, points, b, count, colors);
    ws.hit_count += points.count;
    ws.any_departs |= points.departs != 0;
  }
}

// The level's rays [first, first + count), traced, become `points`: their
// hits' frames come from the hit-frame kernel, all at once; then, ray by ray
// in order (each sample's colour adds up in the same order whatever the
// kernel's width), misses add the background and hits their ambient term.
template <unsigned F>
void WhittedIntegrator::add_packet_hits(Workspace& ws, PacketPoints& points, int first, int count,
                                        Vec3* colors) const {
  const RayLevel& level = ws.level;
  int lanes = 0;
  uint32_t curved = 0;
  for (int i = first; i < first + count; ++i) {
    const TraceHit& hit = ws.hits[i];
    if (hit.geom == RTC_INVALID_GEOMETRY_ID) continue;
    set_hit_lane(points.frames, lanes, level.orgs[i], level.dirs[i], hit.t, hit.ng);
    points.m[lanes] = &surfaces_[embree_.material(hit)];
    curved |= uint32_t(hit.geom != EmbreeScene::kTriangles) << lanes;
    points.owner[lanes++] = i;
  }
  points.count = lanes;
  points.departs = 0;
  if (lanes > 0) {
    embree_.kernels().hit_frames(points.frames, lanes);
    set_shading_normals<F>(ws.hits.data(), points);
    // A sphere or cone hit from the outside: mirror rays off it, and shadow
    // rays to a light in front of it, go away from it (a sphere's or cone's
    // shading normal is its geometric one), and depart it.
    points.departs = curved & points.frames.entering;
  }
  for (int i = first, lane = 0; i < first + count; ++i) {
    const TraceHit& hit = ws.hits[i];
    if (hit.geom == RTC_INVALID_GEOMETRY_ID) {
      colors[level.samples[i]] += background_ * level.weights[i];
      continue;
    }
    colors[level.samples[i]] += points.m[lane++]->ambient * level.weights[i];
  }
}

// One shadow ray per (hit, light in front of it), in packets per light, each
// light with its shadow cache (embree_scene.h), kept for one wavefront's rays.
void WhittedIntegrator::light_level(Workspace& ws, Vec3* colors, RayStats& stats,
                                    EmbreeScene::Origins found_by) const {
  if (ws.shadow_of.size() < ws.hit_count) {  // only grown: filled in place below, as points are
    ws.shadow_orgs.resize(ws.hit_count);
    ws.shadow_dirs.resize(ws.hit_count);
    ws.shadow_of.resize(ws.hit_count);
  }
  for (size_t l = 0; l < lights_.size(); ++l) {
    const LocalLight& light = lights_[l];
    int m = 0;
    for (size_t k = 0; k < ws.packet_count; ++k) {
      const PacketPoints& points = ws.points[k];
      // Light behind: no shadow ray (light_in_front(), in lanes: where it is
      // in front varies from point to point, and gears' five lights made a
      // branch per point mispredict often).
      const uint32_t in_front =
          embree_.kernels().facing(points.frames.p, shading_normals(points), &light.position.x, points.count);
      for (uint32_t bits = in_front; bits; bits &= bits - 1) {
        const int i = __builtin_ctz(bits);
        const Vec3 front = lane_vec(points.frames.p_front, i);
        ws.shadow_orgs[m] = front;
        ws.shadow_dirs[m] = light.position - front;  // t in (0, 1) reaches the light
        ws.shadow_of[m++] = static_cast<int>(k * kPacket + i);
      }
    }
    stats.shadow += m;
    for (int b = 0; b < m; b += kPacket) {
      const int c = std::min(kPacket, m - b);
      bool blocked[kPacket];
      occluded(ws, static_cast<uint32_t>(l), b, c, found_by, blocked);
      add_direct_light(ws, light, &ws.shadow_of[b], blocked, c, colors);
    }
  }
}

// Shadow rays [first, first + count) of light `l`: together, with the
// light's shadow cache, or one by one (EmbreeScene::walks_alone()), each with
// the cache of the primitive it starts on (StartShadowCaches).
void WhittedIntegrator::occluded(Workspace& ws, uint32_t l, int first, int count, EmbreeScene::Origins found_by,
                                 bool* blocked) const {
  const Vec3* orgs = &ws.shadow_orgs[first];
  const Vec3* dirs = &ws.shadow_dirs[first];
  assert(count <= kPacket);
  EmbreeScene::Departure departures[kPacket];
  const EmbreeScene::Departure* departing = nullptr;  // none depart: no departures at all
  if (ws.any_departs) {
    for (int k = 0; k < count; ++k) {
      const int point = ws.shadow_of[first + k];
      const PacketPoints& points = ws.points[point / kPacket];
      departures[k] = departure(embree_, points, point % kPacket, ws.hits[points.owner[point % kPacket]]);
    }
    departing = departures;
  }
  if (!embree_.walks_alone(orgs, dirs, count, found_by)) {
    embree_.occluded_together(orgs, dirs, count, blocked, &ws.shadow_cache[l], departing);
    return;
  }
  EmbreeScene::ShadowCache* caches[kPacket];
  for (int k = 0; k < count; ++k) {
    const int point = ws.shadow_of[first + k];
    const TraceHit& start = ws.hits[ws.points[point / kPacket].owner[point % kPacket]];
    caches[k] = &ws.start_caches.at(start.geom, start.prim, l);
  }
  embree_.occluded_alone(orgs, dirs, count, blocked, caches, departing);
}

// The light's Phong terms at the points[shadow_of[i]] that no blocked[i]
// shadows, from the Phong kernel, all at once; then added in order.
void WhittedIntegrator::add_direct_light(Workspace& ws, const LocalLight& light, const int* shadow_of,
                                         const bool* blocked, int count, Vec3* colors) const {
  int lit[kPacket], n = 0;
  for (int k = 0; k < count; ++k) {
    if (blocked[k]) continue;
    const PacketPoints& points = ws.points[shadow_of[k] / kPacket];
    const int i = shadow_of[k] % kPacket;
    const Surface& m = *points.m[i];
    set_phong_lane(ws.phong, n, light.position - lane_vec(points.frames.p, i), lane_vec(shading_normals(points), i),
                   lane_vec(points.frames.d, i), m.ks, m.shine);
    lit[n++] = shadow_of[k];
  }
  if (n == 0) return;
  embree_.kernels().phong(ws.phong, n);
  const RayLevel& level = ws.level;
  for (int k = 0; k < n; ++k) {
    const PacketPoints& points = ws.points[lit[k] / kPacket];
    const int i = lit[k] % kPacket;
    const int r = points.owner[i];
    const Vec3 c = direct_light(*points.m[i], phong_lane(ws.phong, k), light);
    colors[level.samples[r]] += c * level.weights[r];
  }
}

// The next level: a refraction ray per transmitting hit (Snell), then a mirror
// ray per hit with Ks > 0 or total internal reflection, from the child-ray
// kernel. Refraction rays come first and mirror rays after, so each packet
// stays coherent.
template <unsigned F>
void WhittedIntegrator::spawn_level(Workspace& ws, RayStats& stats) const {
  const RayLevel& level = ws.level;
  ws.next.make_room(2 * ws.hit_count);  // a refraction and a mirror ray per hit, at most
  for (size_t p = 0; p < ws.packet_count; ++p) {
    PacketPoints& points = ws.points[p];
    find_child_rays<F>(points);
    if constexpr ((F & kRefraction) == 0) continue;
    if (!points.spawns_children) continue;
    for (int i = 0; i < points.count; ++i) {
      const Surface& m = *points.m[i];
      const int r = points.owner[i];
      if (!(m.transmittance > 0) || total_internal(points, i) || !worth_spawning(level.weights[r] * m.transmittance)) {
        continue;
      }
      ++stats.refraction;
      ws.next.push(lane_vec(points.children.refract_org, i), lane_vec(points.children.refract_dir, i),
                   level.weights[r] * m.transmittance, level.samples[r], EmbreeScene::Departure{},
                   sphere_inside(points, i, ws.hits[r], true));
    }
  }
  for (size_t p = 0; p < ws.packet_count; ++p) {
    const PacketPoints& points = ws.points[p];
    if (!points.spawns_children) continue;
    for (int i = 0; i < points.count; ++i) {
      const Surface& m = *points.m[i];
      // Ks, and T too where the refraction is total internal reflection.
      const double mirror = m.transmittance > 0 && total_internal(points, i) ? m.ks + m.transmittance : m.ks;
      const int r = points.owner[i];
      if (!(mirror > 0) || !worth_spawning(level.weights[r] * mirror)) continue;
      ++stats.reflection;
      ws.next.push(lane_vec(points.children.mirror_org, i), lane_vec(points.children.mirror_dir, i),
                   level.weights[r] * mirror, level.samples[r], departure(embree_, points, i, ws.hits[r]),
                   sphere_inside(points, i, ws.hits[r], false));
    }
  }
}

// The child rays of the points whose material spawns any (child_rays.h),
// from the kernel; spawns_children says whether there are any.
template <unsigned F>
void WhittedIntegrator::find_child_rays(PacketPoints& points) const {
  constexpr bool kRefracts = (F & kRefraction) != 0;
  points.spawns_children = false;
  for (int i = 0; i < points.count; ++i) {
    const Surface& m = *points.m[i];
    points.spawns_children |= m.ks > 0 || m.transmittance > 0;
    // eta = n_from / n_to; the outside has ior 1.
    if constexpr (kRefracts) points.children.eta[i] = (points.frames.entering >> i) & 1 ? 1.0 / m.ior : m.ior;
  }
  if (points.spawns_children) {
    embree_.kernels().child_rays(points.frames, shading_normals(points), points.children, points.count, kRefracts);
  }
}

}  // namespace rayfarm
