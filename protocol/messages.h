// The message types and constants of RFP/4, the farm protocol (protocol/SPEC.md).
// Plain structs, one per message type, gathered in the Message variant; the
// codec (protocol/codec.h) is the only place that turns them into frames and back.
#pragma once

#include <cstdint>
#include <string>
#include <variant>
#include <vector>

#include "tracer/nff_reader.h"
#include "tracer/ray_stats.h"
#include "tracer/render_settings.h"

namespace rayfarm::protocol {

// RFP/4: RFP/3 with pixel spans: `task` and `result` carry x0, x1, the pixels
// of each row (a tail row goes out in spans). RFP/3 made `result` one binary
// frame (its timings and ray counts in the fixed header), the broker's most
// frequent message.
inline constexpr int kVersion = 4;
inline constexpr uint16_t kResultLayout = 3;  // the binary result layout (2 was RFP/3's, without x0, x1)
inline constexpr uint32_t kResultHeaderBytes = 112;
inline constexpr char kResultMagic[4] = {'R', 'F', 'P', 'X'};

// Limits a decoder enforces before allocating anything for a peer.
inline constexpr size_t kMaxJsonBytes = 1u << 20;
inline constexpr size_t kMaxSceneBytes = rayfarm::kMaxSceneBytes;  // a scene file's limit (tracer/nff_reader.h)
inline constexpr size_t kMaxResultBytes = 256u << 20;
inline constexpr int kMaxDimension = 65536;
inline constexpr uint64_t kMaxJobId = (uint64_t{1} << 53) - 1;  // exact in JSON doubles
inline constexpr int kMaxCredit = 64;
inline constexpr size_t kMaxReasonBytes = 4096;
inline constexpr size_t kMaxNameBytes = 128;  // a worker's name

// How long a peer may stay silent before it counts as lost: `liveness` of its
// heartbeat intervals, but never fewer than two. A peer heartbeats only after
// a whole quiet interval (a little later on a busy machine), so a limit of
// one interval (liveness 1) ran out on every quiet link at its first heartbeat.
inline constexpr int kMinSilentIntervals = 2;
constexpr int64_t silence_limit_ms(int heartbeat_ms, int liveness) {
  return int64_t{heartbeat_ms} * (liveness < kMinSilentIntervals ? kMinSilentIntervals : liveness);
}

// Bytes of the frame of a `result` of `rows` x `width` pixels: the largest
// legitimate worker -> broker frame, from which a broker sizes its
// ZMQ_MAXMSGSIZE (see broker/broker_config.h).
constexpr uint64_t result_frame_bytes(int width, int rows) {
  return kResultHeaderBytes + uint64_t{static_cast<uint32_t>(width)} * static_cast<uint32_t>(rows) * 3 * sizeof(float);
}

// ---- broker -> worker -------------------------------------------------------
struct Welcome {
  int heartbeat_ms = 1000;
  int liveness = 3;
  int pub_port = 1;
  uint64_t job = 0;  // current job, 0 = none
};

struct Heartbeat {
  uint64_t job = 0;  // broker: current job; worker: job it has loaded
};

// A job and its scene. Published to all workers and sent on `fetch_job`.
struct JobSpec {
  uint64_t job = 0;
  uint64_t scene_hash = 0;  // fnv1a64(scene_text)
  std::string scene_name;
  RenderSettings settings;  // `threads` is not transmitted
  std::string scene_text;
};

struct TaskAssign {
  uint64_t job = 0;
  uint32_t task = 0;
  uint32_t attempt = 1;
  int y0 = 0, y1 = 0;
  int x0 = 0, x1 = 0;  // pixels of each row: [0, width) for whole rows, else a span of one row
};

// What is wrong with rows [y0, y1) and pixels [x0, x1) of an image `width`
// pixels wide, naming the fields; empty when nothing is. The one rule for
// tasks and results: 0 <= x0 < x1 <= width, and a span (anything but the
// whole row) is one row.
std::string pixel_band_problem(int y0, int y1, int x0, int x1, int width);

struct Reregister {
  std::string reason;
};

struct Shutdown {};

// ---- worker -> broker -------------------------------------------------------
struct Ready {
  std::string name;
  double weight = 21.0;
  int threads = 0;
  int credit = 2;
  int heartbeat_ms = 1000;
  double throttle = 1.0;
};

struct FetchJob {
  uint64_t job = 0;
};

struct JobReady {
  uint64_t job = 0;
  double init_s = 0;  // scene parse + BVH build on the worker
};

struct TaskResult {
  uint64_t job = 0;
  uint32_t task = 0;
  uint32_t attempt = 1;
  int y0 = 0, y1 = 0, width = 0;
  int x0 = 0, x1 = 0;     // pixels of each row, as in TaskAssign
  double render_s = 0;    // time in Renderer::render_rows / render_span
  double throttle_s = 0;  // time slept to emulate a slower machine
  RayStats stats;
  std::vector<float> rgb;  // (y1 - y0) * (x1 - x0) * 3
};

struct Bye {};

// The worker cannot load or render `job` and has dropped it (it stays up for
// the next one). `scope` says where the fault is: in the job itself (the scene
// or settings; every worker would fail) or in this worker (e.g. out of memory).
enum class FailureScope { job, worker };
struct JobFailed {
  uint64_t job = 0;
  FailureScope scope = FailureScope::job;
  std::string reason;  // e.g. "balls.nff:12: expected 4 numbers after 's'"
};
const char* scope_name(FailureScope scope);

// ---- announcements (PUB) ------------------------------------------------------
struct JobDone {
  uint64_t job = 0;
};

using Message = std::variant<Welcome, Heartbeat, JobSpec, TaskAssign, Reregister, Shutdown,
                             Ready, FetchJob, JobReady, TaskResult, Bye, JobDone, JobFailed>;

// The wire name of a message type, e.g. "task".
const char* type_name(const Message& m);

}  // namespace rayfarm::protocol
