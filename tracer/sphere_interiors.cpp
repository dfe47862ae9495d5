// EmbreeScene's sphere interiors (Interior in embree_scene.h): which
// primitives reach into each sphere a ray can be inside, found once after
// the build, and the walk-free test of rays inside one, intersect_inside().
#include <algorithm>
#include <cmath>

#include "tracer/embree_scene.h"

#include "tracer/box.h"
#include "tracer/ray_lane_fill.h"

namespace rayfarm {

namespace {

// More primitives than this reaching into a sphere and its inside rays walk
// as any others.
constexpr size_t kMaxIntruders = InteriorLaneShape::kMaxCaps;

// How far beyond its radius a sphere's interior reaches, and how much room
// the caps leave, relative to the sphere's size and distance from the local
// origin: far above the rounding of a ray's start, of its exit point and of
// the caps' planes (parts in 10^16), and small enough to list little more
// than what touches the sphere.
constexpr double kSlack = 1e-6;

struct IntruderSearch {
  uint32_t sphere;
  std::vector<EmbreeScene::Occluder>* found;
};

bool collect_intruder(RTCPointQueryFunctionArguments* args) {
  auto* search = static_cast<IntruderSearch*>(args->userPtr);
  if (!(args->geomID == EmbreeScene::kSpheres && args->primID == search->sphere)) {
    search->found->push_back({args->geomID, args->primID});
  }
  return false;  // the query's radius is unchanged
}

}  // namespace

// The cap of a sphere in which primitive `o`, which reaches into it, can
// be met, `slack` short of the exact one: for a sphere, the side of the
// plane through the nearest point of its ball; for any other primitive,
// of the plane through the nearest corner of its widened box, which holds
// every hit its test reports (a triangle's hits beyond this piece's box lie
// in another piece's, which reaches in too).
void EmbreeScene::set_cap(uint32_t sphere, const Occluder& o, double slack, double* axis, double& level) const {
  const LocalSphere& s = spheres_[sphere];
  axis[0] = 1, axis[1] = axis[2] = 0;
  level = -HUGE_VAL;  // met anywhere, unless a plane is found
  auto set_axis = [&](const Vec3& towards) {
    const double length = std::sqrt(dot(towards, towards));
    if (!(length > 0)) return false;
    axis[0] = towards.x / length, axis[1] = towards.y / length, axis[2] = towards.z / length;
    return true;
  };
  if (o.geom == kSpheres) {
    const LocalSphere& other = spheres_[o.prim];
    const Vec3 apart = other.center - s.center;
    if (set_axis(apart)) level = std::sqrt(dot(apart, apart)) - other.radius - slack;
    return;
  }
  const Vec3 margin{box_margin_, box_margin_, box_margin_};
  const Box narrow = o.geom == kCones ? slice_box(o.prim) : piece_boxes_[o.prim];
  const Box box{narrow.lo - margin, narrow.hi + margin};
  if (!set_axis(0.5 * (box.lo + box.hi) - s.center)) return;
  const Vec3 unit{axis[0], axis[1], axis[2]};
  double nearest = HUGE_VAL;
  for (const Vec3& corner : box_corners(box)) nearest = std::min(nearest, dot(corner - s.center, unit));
  level = nearest - slack;
}

// Embree's point query hands over every primitive whose box (widened as for
// the walk, so holding every hit its exact test reports) meets a ball; the
// ball is grown well beyond the float rounding of its centre and of the
// query's box distances, so the list is a superset of the primitives a ray
// inside the sphere can meet before it leaves.
void EmbreeScene::find_interiors(const Scene& scene) {
  auto transmits = [&](uint32_t material) {
    return material < scene.materials.size() && scene.materials[material].transmittance > 0;
  };
  const std::vector<uint32_t>& materials = materials_[kSpheres];
  if (std::none_of(materials.begin(), materials.end(), transmits)) return;
  interior_of_.assign(spheres_.size(), kNotListed);
  std::vector<Occluder> found;
  for (uint32_t i = 0; i < spheres_.size(); ++i) {
    if (!transmits(materials[i])) continue;  // no ray gets inside an opaque sphere but the eye's
    const LocalSphere& s = spheres_[i];
    const double scale = s.radius + std::sqrt(dot(s.center, s.center));
    const double reach = s.radius + kSlack * scale;
    RTCPointQuery query;
    query.x = static_cast<float>(s.center.x);
    query.y = static_cast<float>(s.center.y);
    query.z = static_cast<float>(s.center.z);
    query.time = 0;
    query.radius = static_cast<float>(reach + 1e-5 * scale);
    RTCPointQueryContext context;
    rtcInitPointQueryContext(&context);
    found.clear();
    IntruderSearch search{i, &found};
    rtcPointQuery(scene_, &query, &context, collect_intruder, &search);
    if (found.size() > kMaxIntruders) continue;
    Interior in;
    in.shape.center[0] = s.center.x, in.shape.center[1] = s.center.y, in.shape.center[2] = s.center.z;
    in.shape.radius = s.radius;
    in.shape.reach2 = reach * reach;
    in.shape.caps = static_cast<int>(found.size());
    for (size_t k = 0; k < found.size(); ++k) {
      in.intruders[k] = found[k];
      set_cap(i, found[k], kSlack * scale, in.shape.axis[k], in.shape.level[k]);
    }
    interior_of_[i] = static_cast<uint32_t>(interiors_.size());
    interiors_.push_back(in);
  }
}

// Rays that start inside a sphere skip the walk: each meets the sphere, and
// those of the primitives that reach into it (find_interiors()) whose cap
// its segment enters, through the lane kernels the callbacks run, nearest
// by the same tie rule; so each gets the hit a walk would give it. That
// holds for a ray whose start and exit lie within the interior's reach: the
// segment between them, where any nearer hit lies, lies within it too,
// where only the intruders' boxes reach, and enters an intruder's cap only
// if one of its ends lies in it (a cap is convex). Any other ray of the
// packet is walked alone.
void EmbreeScene::intersect_inside(uint32_t sphere, const Vec3* orgs, const Vec3* dirs, int count,
                                   TraceHit* hits) const {
  thread_local RayLanes soa;
  alignas(64) FloatLanes floats;
  fill_lanes(orgs, dirs, count, HUGE_VAL, soa, floats);
  const Interior& interior = interiors_[interior_of_[sphere]];
  const LocalSphere& s = spheres_[sphere];
  alignas(64) double t[kPacket] = {};  // the kernel reads a whole group's t, missed lanes too
  uint32_t beyond[InteriorLaneShape::kMaxCaps];
  const uint32_t sure = lane_kernels_.interior(soa, (1u << count) - 1, interior.shape, t, beyond);
  for (uint32_t bits = sure; bits; bits &= bits - 1) {
    const int i = __builtin_ctz(bits);
    TraceHit& hit = hits[i];
    hit.t = t[i];
    hit.ng = lane_sphere_normal(soa, i, s.center, t[i]);
    hit.geom = kSpheres;
    hit.prim = sphere;
    hit.u = hit.v = 0;
  }
  for (int k = 0; k < interior.shape.caps; ++k) {
    if (beyond[k]) meet_intruder(interior.intruders[k], soa, beyond[k], hits);
  }
  for (int i = 0; i < count; ++i) {
    if (!((sure >> i) & 1) && !intersect(orgs[i], dirs[i], hits[i])) hits[i].geom = RTC_INVALID_GEOMETRY_ID;
  }
}

}  // namespace rayfarm
