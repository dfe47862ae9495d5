// NFF reader: turns Eric Haines' Neutral File Format text into a Scene.
// Tokens are separated by any whitespace (the SPD library and the NFF document
// lay out `c` differently), `#` starts a comment anywhere, a leading UTF-8
// byte-order mark is skipped, and every error names its place:
// "name:line: expected ...".
//
// Validation policy.
//  * Errors (InputError): malformed or unusable input -- missing or second `v`
//    block, `v` keywords out of order, truncated entities, non-numeric or
//    non-finite numbers or numbers beyond +-kMaxSceneMagnitude, unknown
//    keywords, resolution outside 1..65536, angle
//    outside (0, 180), zero `up`, `up` parallel to the view, from == at,
//    negative hither, `p`/`pp` with fewer than 3 or more than
//    kMaxPolygonVertices vertices, negative sphere or
//    cone radii (inside-visible primitives are not supported), negative Shine,
//    T > 0 with ior <= 0.
//  * Warnings (Scene::warnings, "name:line: ..."): well-formed but degenerate
//    geometry, which is skipped or repaired so that nothing downstream sees a
//    NaN: zero-radius spheres and cones with both radii 0 or base == apex are
//    skipped; polygons lose consecutive repeated vertices and are skipped if
//    they have no area left; a zero-length `pp` normal is replaced by the
//    polygon's face normal.
//  * Order: the `v` block may come anywhere (the SPD always writes it before the
//    geometry, after `b`); exactly one is required.
//  * Materials: primitives before the first `f` get a default material
//    (white, Kd 1, no Ks/T), appended to Scene::materials when first needed.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>

#include "tracer/scene.h"

namespace rayfarm {

// No number in a scene may exceed this magnitude. Embree accepts a ray only if
// every origin and direction component is within FLT_LARGE (1.844e18, its
// ray.valid() check, an assertion in Debian's build that aborts the process):
// a light at 1e19 makes shadow-ray directions of ~1e19 and kills the renderer.
// Ray components are sums and differences of a few scene numbers, so 1e16
// leaves a factor 100 of headroom, and no real scene comes near it.
inline constexpr double kMaxSceneMagnitude = 1e16;

// No scene file may be larger: the farm sends a scene in one frame, whose
// limit (protocol::kMaxSceneBytes) is this one, and a path that names
// /dev/zero or an endless FIFO must fail, not read until memory runs out.
inline constexpr size_t kMaxSceneBytes = 256u << 20;

// No polygon may have more vertices. Ear clipping (triangulate.h) takes time
// growing with the square of a polygon's vertices and more: a concave polygon
// of 4,096 took 0.08 s to build, of 8,192 0.4 s, of 16,384 1.2 s, and of
// 100,000 45 s, so one line of a scene within the size limit could stall a
// worker for hours. The SPD's largest polygons have 144.
inline constexpr int kMaxPolygonVertices = 4096;

}  // namespace rayfarm

namespace rayfarm {

// Parses NFF text; `name` is used in messages ("name:line: ..."). Throws InputError.
Scene parse_nff(std::string_view text, const std::string& name);

// A scene file's bytes, from a file of any kind (a pipe from `<(...)` too);
// InputError "path: cannot open ..." when unreadable, "path: larger than the
// 256 MiB scene limit" past kMaxSceneBytes.
std::string read_nff_text(const std::string& path);

// Reads and parses a file; InputError as read_nff_text.
Scene read_nff_file(const std::string& path);

}  // namespace rayfarm
