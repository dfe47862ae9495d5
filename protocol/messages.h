// The message types and constants of RFP/3, the farm protocol (protocol/SPEC.md).
// Plain structs, one per message type, gathered in the Message variant; the
// codec (protocol/codec.h) is the only place that turns them into frames and back.
#pragma once

#include <cstdint>
#include <string>
#include <variant>
#include <vector>

#include "tracer/ray_stats.h"
#include "tracer/render_settings.h"

namespace rayfarm::protocol {

// RFP/3: RFP/2 with `result` as one binary frame (its timings and ray counts
// moved from JSON into the fixed header), the broker's most frequent message.
inline constexpr int kVersion = 3;
inline constexpr uint16_t kResultLayout = 2;  // the binary result layout (1 was RFP/2's pixel frame)
inline constexpr uint32_t kResultHeaderBytes = 104;
inline constexpr char kResultMagic[4] = {'R', 'F', 'P', 'X'};

// Limits a decoder enforces before allocating anything for a peer.
inline constexpr size_t kMaxJsonBytes = 1u << 20;
inline constexpr size_t kMaxSceneBytes = 256u << 20;
inline constexpr size_t kMaxResultBytes = 256u << 20;
inline constexpr int kMaxDimension = 65536;
inline constexpr uint64_t kMaxJobId = (uint64_t{1} << 53) - 1;  // exact in JSON doubles
inline constexpr int kMaxCredit = 64;
inline constexpr size_t kMaxReasonBytes = 4096;

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
};

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
  double render_s = 0;    // time in Renderer::render_rows
  double throttle_s = 0;  // time slept to emulate a slower machine
  RayStats stats;
  std::vector<float> rgb;  // (y1 - y0) * width * 3
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
