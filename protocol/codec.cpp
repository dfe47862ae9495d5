// RFP/3 encoding and validating decoding; the grammar is protocol/SPEC.md.
#include "protocol/codec.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <map>

#include <nlohmann/json.hpp>

#include "protocol/json_fields.h"
#include "tracer/text_file.h"

namespace rayfarm::protocol {
namespace {

using nlohmann::json;

static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__,
              "the result frame is little-endian; add byte swapping for this host");
static_assert(sizeof(float) == 4);

// ---- JSON frame ---------------------------------------------------------------

json header(const char* type) { return json{{"v", kVersion}, {"type", type}}; }

json settings_json(const RenderSettings& s) {
  return {{"width", s.width}, {"height", s.height}, {"spp", s.spp}, {"max_depth", s.max_depth},
          {"seed", s.seed}, {"adaptive_contrast", s.adaptive_contrast}, {"cutoff", s.cutoff}, {"robust_bvh", s.robust_bvh}};
}

// The JSON ranges keep every value representable; validate_settings (the same
// rule `render` applies) then decides whether the settings are renderable.
RenderSettings read_settings(JsonFields f) {
  RenderSettings s;
  s.width = static_cast<int>(f.integer("width", INT32_MIN, INT32_MAX));
  s.height = static_cast<int>(f.integer("height", INT32_MIN, INT32_MAX));
  s.spp = static_cast<int>(f.integer("spp", INT32_MIN, INT32_MAX));
  s.max_depth = static_cast<int>(f.integer("max_depth", INT32_MIN, INT32_MAX));
  s.seed = f.unsigned64("seed");
  s.adaptive_contrast = f.number("adaptive_contrast", 0, kMaxAdaptiveContrast);
  s.cutoff = f.number("cutoff", 0, 1);
  s.robust_bvh = f.boolean("robust_bvh");
  f.finish();
  try {
    validate_settings(s);
  } catch (const InputError& e) {
    throw ProtocolError(std::string("settings.") + e.what());
  }
  return s;
}

// ---- binary result frame ------------------------------------------------------
// The one message a busy broker receives per task is a fixed little-endian
// layout (protocol/SPEC.md, "Result frame"): no JSON to parse, and every field
// at a known offset.

namespace result_at {  // byte offsets of the header fields
constexpr size_t version = 4, header_size = 6, job = 8, task = 16, attempt = 20, y0 = 24, y1 = 28, width = 32,
                 reserved = 36, render_s = 40, throttle_s = 48, stats = 56,  // stats: 6 x u64
                 x0 = 104, x1 = 108;  // appended in layout 3: the fields before keep their offsets
}  // namespace result_at
static_assert(result_at::x1 + 4 == kResultHeaderBytes);

template <class T> void put_le(std::string& out, size_t at, T v) { std::memcpy(&out[at], &v, sizeof v); }
template <class T> T get_le(const std::string& in, size_t at) {
  T v;
  std::memcpy(&v, &in[at], sizeof v);
  return v;
}

// The ray counts in header order.
std::array<uint64_t*, 6> stat_fields(RayStats& r) {
  return {&r.eye, &r.eye_hit, &r.shadow, &r.reflection, &r.refraction, &r.non_finite};
}

std::string encode_result(const TaskResult& r) {
  const size_t floats = static_cast<size_t>(r.y1 - r.y0) * static_cast<size_t>(r.x1 - r.x0) * 3;
  std::string out(kResultHeaderBytes + floats * 4, '\0');
  std::memcpy(&out[0], kResultMagic, 4);
  put_le<uint16_t>(out, result_at::version, kResultLayout);
  put_le<uint16_t>(out, result_at::header_size, kResultHeaderBytes);
  put_le<uint64_t>(out, result_at::job, r.job);
  put_le<uint32_t>(out, result_at::task, r.task);
  put_le<uint32_t>(out, result_at::attempt, r.attempt);
  put_le<uint32_t>(out, result_at::y0, static_cast<uint32_t>(r.y0));
  put_le<uint32_t>(out, result_at::y1, static_cast<uint32_t>(r.y1));
  put_le<uint32_t>(out, result_at::width, static_cast<uint32_t>(r.width));
  put_le<uint32_t>(out, result_at::reserved, 0);
  put_le<uint32_t>(out, result_at::x0, static_cast<uint32_t>(r.x0));
  put_le<uint32_t>(out, result_at::x1, static_cast<uint32_t>(r.x1));
  put_le<double>(out, result_at::render_s, r.render_s);
  put_le<double>(out, result_at::throttle_s, r.throttle_s);
  RayStats stats = r.stats;
  const auto fields = stat_fields(stats);
  for (size_t i = 0; i < fields.size(); ++i) put_le<uint64_t>(out, result_at::stats + 8 * i, *fields[i]);
  if (floats) std::memcpy(&out[kResultHeaderBytes], r.rgb.data(), floats * 4);
  return out;
}

constexpr double kMaxSeconds = 1e9;

// `whose`: the task the result claims to be, said only on a rejection.
template <class Whose> double read_seconds(const std::string& in, size_t at, const char* name, const Whose& whose) {
  const double v = get_le<double>(in, at);
  if (!(v >= 0 && v <= kMaxSeconds))  // also catches NaN
    throw ProtocolError(std::string("result.") + name + whose() + ": expected a number in [0, 1e9], found " +
                        std::to_string(v));
  return v;
}

// The rest of a result whose job, task and attempt are read into `r`: rows,
// width, pixels, timings, ray counts, the frame length, the pixel values.
void read_result_content(const std::string& in, TaskResult& r) {
  const uint32_t y0 = get_le<uint32_t>(in, result_at::y0), y1 = get_le<uint32_t>(in, result_at::y1);
  const uint32_t width = get_le<uint32_t>(in, result_at::width);
  if (y1 > static_cast<uint32_t>(kMaxDimension) || y0 >= y1)
    throw ProtocolError("result.y0/y1: rows [" + std::to_string(y0) + ", " + std::to_string(y1) + ") out of range");
  if (width == 0 || width > static_cast<uint32_t>(kMaxDimension))
    throw ProtocolError("result.width: width " + std::to_string(width) + " out of range");
  if (get_le<uint32_t>(in, result_at::reserved) != 0) throw ProtocolError("result.reserved: must be 0");
  // Both at most 65536 here, so the int conversions below are exact.
  const uint32_t x0 = std::min(get_le<uint32_t>(in, result_at::x0), uint32_t{kMaxDimension} + 1);
  const uint32_t x1 = std::min(get_le<uint32_t>(in, result_at::x1), uint32_t{kMaxDimension} + 1);
  const std::string bad = pixel_band_problem(static_cast<int>(y0), static_cast<int>(y1), static_cast<int>(x0),
                                             static_cast<int>(x1), static_cast<int>(width));
  if (!bad.empty()) throw ProtocolError("result." + bad);
  // From here the header names a task that may exist: a rejection says which
  // (and its rows), so the broker's log line points at the task as well as
  // the peer. Built only on a rejection: an accepted result builds no strings.
  const auto whose = [&] {
    const auto band = [](int a, int b) { return "[" + std::to_string(a) + ", " + std::to_string(b) + ")"; };
    const bool span = x0 > 0 || x1 < width;
    return " of task " + std::to_string(r.task) + " attempt " + std::to_string(r.attempt) + " (job " +
           std::to_string(r.job) + ", rows " + band(static_cast<int>(y0), static_cast<int>(y1)) +
           (span ? ", pixels " + band(static_cast<int>(x0), static_cast<int>(x1)) : std::string()) + ")";
  };
  r.render_s = read_seconds(in, result_at::render_s, "render_s", whose);
  r.throttle_s = read_seconds(in, result_at::throttle_s, "throttle_s", whose);
  const auto fields = stat_fields(r.stats);
  for (size_t i = 0; i < fields.size(); ++i) *fields[i] = get_le<uint64_t>(in, result_at::stats + 8 * i);
  // 64-bit arithmetic: at most 65536 * 65536 * 12 bytes, no overflow.
  const uint64_t floats = uint64_t{y1 - y0} * (x1 - x0) * 3;
  const uint64_t want = kResultHeaderBytes + floats * 4;
  if (in.size() != want)
    throw ProtocolError("result" + whose() + ": frame is " + std::to_string(in.size()) +
                        " bytes, rows * (x1 - x0) * 3 * 4 + " + std::to_string(kResultHeaderBytes) + " = " +
                        std::to_string(want));
  r.y0 = static_cast<int>(y0);
  r.y1 = static_cast<int>(y1);
  r.width = static_cast<int>(width);
  r.x0 = static_cast<int>(x0);
  r.x1 = static_cast<int>(x1);
  r.rgb.resize(floats);
  std::memcpy(r.rgb.data(), in.data() + kResultHeaderBytes, floats * 4);
  for (size_t i = 0; i < r.rgb.size(); ++i)
    if (!std::isfinite(r.rgb[i])) {
      const size_t pixel = i / 3, span_width = x1 - x0;
      throw ProtocolError("result" + whose() + ": non-finite pixel value at x " +
                          std::to_string(x0 + pixel % span_width) + " of row " + std::to_string(y0 + pixel / span_width));
    }
}

// Checks the header field by field before trusting any size in it, then the
// exact frame length, so a short frame claiming 65536 x 65536 pixels is
// rejected without allocating anything. The layout comes first (magic,
// version, header size), then the task the result names; a rejection after
// that keeps the task (ResultContentError), so a broker can requeue it.
TaskResult decode_result(const std::string& in) {
  if (in.size() < kResultHeaderBytes)
    throw ProtocolError("result: frame of " + std::to_string(in.size()) + " bytes is shorter than the " +
                        std::to_string(kResultHeaderBytes) + "-byte header");
  if (in.size() > kMaxResultBytes) throw ProtocolError("result: frame larger than 256 MiB");
  if (get_le<uint16_t>(in, result_at::version) != kResultLayout)
    throw ProtocolError("result.version: unsupported result layout " +
                        std::to_string(get_le<uint16_t>(in, result_at::version)) + " (this is " +
                        std::to_string(kResultLayout) + ", protocol version " + std::to_string(kVersion) + ")");
  if (get_le<uint16_t>(in, result_at::header_size) != kResultHeaderBytes)
    throw ProtocolError("result.header_size: must be " + std::to_string(kResultHeaderBytes));
  TaskResult r;
  r.job = get_le<uint64_t>(in, result_at::job);
  r.task = get_le<uint32_t>(in, result_at::task);
  r.attempt = get_le<uint32_t>(in, result_at::attempt);
  if (r.job == 0 || r.job > kMaxJobId) throw ProtocolError("result.job: job id out of range");
  if (r.attempt == 0) throw ProtocolError("result.attempt: must be >= 1");
  try {
    read_result_content(in, r);
  } catch (const ProtocolError& e) {
    throw ResultContentError(e.what(), r.job, r.task, r.attempt);
  }
  return r;
}

bool is_result_frame(const std::string& frame) {
  return frame.size() >= 4 && std::memcmp(frame.data(), kResultMagic, 4) == 0;
}

// ---- per-type encoders --------------------------------------------------------

struct Encoder {
  Frames operator()(const Welcome& m) const {
    json j = header("welcome");
    j["heartbeat_ms"] = m.heartbeat_ms;
    j["liveness"] = m.liveness;
    j["pub_port"] = m.pub_port;
    j["job"] = m.job;
    return {j.dump()};
  }
  Frames operator()(const Heartbeat& m) const {
    json j = header("heartbeat");
    j["job"] = m.job;
    return {j.dump()};
  }
  Frames operator()(const JobSpec& m) const {
    json j = header("job");
    j["job"] = m.job;
    j["scene_hash"] = hash_hex(m.scene_hash);
    j["scene_name"] = m.scene_name;
    j["settings"] = settings_json(m.settings);
    return {j.dump(), m.scene_text};
  }
  // The broker's most frequent message, formatted directly: building a JSON
  // tree per task was a third of the broker's time per dispatch. Same keys
  // and values as the tree would give.
  Frames operator()(const TaskAssign& m) const {
    char buf[200];
    const int n = std::snprintf(buf, sizeof buf,
                                R"({"attempt":%u,"job":%llu,"task":%u,"type":"task","v":%d,"x0":%d,"x1":%d,"y0":%d,"y1":%d})",
                                m.attempt, static_cast<unsigned long long>(m.job), m.task, kVersion, m.x0, m.x1, m.y0, m.y1);
    return {std::string(buf, static_cast<size_t>(n))};
  }
  Frames operator()(const Reregister& m) const {
    json j = header("reregister");
    j["reason"] = m.reason;
    return {j.dump()};
  }
  Frames operator()(const Shutdown&) const { return {header("shutdown").dump()}; }
  Frames operator()(const Ready& m) const {
    json j = header("ready");
    j["name"] = m.name;
    j["weight"] = m.weight;
    j["threads"] = m.threads;
    j["credit"] = m.credit;
    j["heartbeat_ms"] = m.heartbeat_ms;
    j["throttle"] = m.throttle;
    return {j.dump()};
  }
  Frames operator()(const FetchJob& m) const {
    json j = header("fetch_job");
    j["job"] = m.job;
    return {j.dump()};
  }
  Frames operator()(const JobReady& m) const {
    json j = header("job_ready");
    j["job"] = m.job;
    j["init_s"] = m.init_s;
    return {j.dump()};
  }
  Frames operator()(const TaskResult& m) const { return {encode_result(m)}; }
  Frames operator()(const Bye&) const { return {header("bye").dump()}; }
  Frames operator()(const JobFailed& m) const {
    json j = header("job_failed");
    j["job"] = m.job;
    j["scope"] = scope_name(m.scope);
    j["reason"] = m.reason;
    return {j.dump()};
  }
  Frames operator()(const JobDone& m) const {
    json j = header("job_done");
    j["job"] = m.job;
    return {j.dump()};
  }
};

// ---- per-type decoders --------------------------------------------------------
// One table row per message type: how many frames it takes and how its JSON
// keys are read. JsonFields range-checks every value and decode() calls
// finish(), so a key that is not read here is an "unknown key" error.

struct TypeRule {
  size_t frames;
  std::function<Message(JsonFields&, const Frames&)> read;
};

uint64_t job_id(JsonFields& f, bool allow_zero) {
  const uint64_t id = f.unsigned64("job", kMaxJobId);
  if (!allow_zero && id == 0) throw ProtocolError("job: expected a job id >= 1");
  return id;
}

const std::map<std::string, TypeRule>& rules() {
  static const std::map<std::string, TypeRule> table = {
      {"welcome", {1, [](JsonFields& f, const Frames&) -> Message {
         Welcome m;
         m.heartbeat_ms = static_cast<int>(f.integer("heartbeat_ms", 10, 600000));
         m.liveness = static_cast<int>(f.integer("liveness", 1, 100));
         m.pub_port = static_cast<int>(f.integer("pub_port", 1, 65535));
         m.job = job_id(f, true);
         return m;
       }}},
      {"heartbeat", {1, [](JsonFields& f, const Frames&) -> Message { return Heartbeat{job_id(f, true)}; }}},
      {"job", {2, [](JsonFields& f, const Frames& frames) -> Message {
         JobSpec m;
         m.job = job_id(f, false);
         const std::string hex = f.string("scene_hash", 16, 16);
         if (hex.find_first_not_of("0123456789abcdef") != std::string::npos)
           throw ProtocolError("scene_hash: expected 16 lowercase hex digits");
         m.scene_hash = std::stoull(hex, nullptr, 16);
         m.scene_name = f.string("scene_name", 0, 4096);
         m.settings = read_settings(f.object("settings"));
         if (frames[1].size() > kMaxSceneBytes) throw ProtocolError("scene: larger than 256 MiB");
         if (fnv1a64(frames[1]) != m.scene_hash)
           throw ProtocolError("scene: text does not match scene_hash " + hex);
         m.scene_text = frames[1];
         return m;
       }}},
      {"task", {1, [](JsonFields& f, const Frames&) -> Message {
         TaskAssign m;
         m.job = job_id(f, false);
         m.task = static_cast<uint32_t>(f.integer("task", 0, UINT32_MAX));
         m.attempt = static_cast<uint32_t>(f.integer("attempt", 1, UINT32_MAX));
         m.y0 = static_cast<int>(f.integer("y0", 0, kMaxDimension - 1));
         m.y1 = static_cast<int>(f.integer("y1", 1, kMaxDimension));
         if (m.y1 <= m.y0) throw ProtocolError("y1: must be greater than y0");
         // The width is the job's: the worker checks x1 against it (pixel_band_problem).
         m.x0 = static_cast<int>(f.integer("x0", 0, kMaxDimension - 1));
         m.x1 = static_cast<int>(f.integer("x1", 1, kMaxDimension));
         if (m.x1 <= m.x0) throw ProtocolError("x1: must be greater than x0");
         if (m.x0 > 0 && m.y1 - m.y0 != 1) throw ProtocolError("x0: a pixel span (x0 > 0) must be one row");
         return m;
       }}},
      {"reregister", {1, [](JsonFields& f, const Frames&) -> Message { return Reregister{f.string("reason", 0, 4096)}; }}},
      {"shutdown", {1, [](JsonFields&, const Frames&) -> Message { return Shutdown{}; }}},
      {"ready", {1, [](JsonFields& f, const Frames&) -> Message {
         Ready m;
         m.name = f.string("name", 1, kMaxNameBytes);
         m.weight = f.number("weight", 0, 1e6);
         if (m.weight <= 0) throw ProtocolError("weight: must be > 0");
         m.threads = static_cast<int>(f.integer("threads", 0, 4096));
         m.credit = static_cast<int>(f.integer("credit", 1, kMaxCredit));
         m.heartbeat_ms = static_cast<int>(f.integer("heartbeat_ms", 10, 600000));
         m.throttle = f.number("throttle", 1, 1000);
         return m;
       }}},
      {"fetch_job", {1, [](JsonFields& f, const Frames&) -> Message { return FetchJob{job_id(f, false)}; }}},
      {"job_ready", {1, [](JsonFields& f, const Frames&) -> Message {
         JobReady m;
         m.job = job_id(f, false);
         m.init_s = f.number("init_s", 0, kMaxSeconds);
         return m;
       }}},
      {"bye", {1, [](JsonFields&, const Frames&) -> Message { return Bye{}; }}},
      {"job_done", {1, [](JsonFields& f, const Frames&) -> Message { return JobDone{job_id(f, false)}; }}},
      {"job_failed", {1, [](JsonFields& f, const Frames&) -> Message {
         JobFailed m;
         m.job = job_id(f, false);
         const std::string scope = f.string("scope", 1, 16);
         if (scope == scope_name(FailureScope::job))
           m.scope = FailureScope::job;
         else if (scope == scope_name(FailureScope::worker))
           m.scope = FailureScope::worker;
         else
           throw ProtocolError("scope: expected \"job\" or \"worker\", found \"" + scope + "\"");
         m.reason = f.string("reason", 1, kMaxReasonBytes);
         return m;
       }}},
  };
  return table;
}

}  // namespace

const char* type_name(const Message& m) {
  static const char* names[] = {"welcome", "heartbeat", "job",       "task",   "reregister", "shutdown",  "ready",
                                "fetch_job", "job_ready", "result", "bye",        "job_done", "job_failed"};
  static_assert(std::variant_size_v<Message> == 13);
  return names[m.index()];
}

std::string pixel_band_problem(int y0, int y1, int x0, int x1, int width) {
  const auto band = [](const char* what, int a, int b) {
    return std::string(what) + " [" + std::to_string(a) + ", " + std::to_string(b) + ")";
  };
  if (!(0 <= x0 && x0 < x1 && x1 <= width))
    return "x0/x1: " + band("pixels", x0, x1) + " out of range for width " + std::to_string(width);
  if ((x0 > 0 || x1 < width) && y1 - y0 != 1)
    return "x0/x1: a span of " + band("pixels", x0, x1) + " must be one row, not " + band("rows", y0, y1);
  return {};
}

const char* scope_name(FailureScope scope) { return scope == FailureScope::job ? "job" : "worker"; }

Frames encode(const Message& message) { return std::visit(Encoder{}, message); }

Message decode(const Frames& frames) {
  if (frames.empty() || frames.size() > 2)
    throw ProtocolError("expected 1 or 2 frames, got " + std::to_string(frames.size()));
  if (is_result_frame(frames[0])) {
    if (frames.size() != 1) throw ProtocolError("'result' takes 1 frame, got " + std::to_string(frames.size()));
    return decode_result(frames[0]);
  }
  if (frames[0].size() > kMaxJsonBytes) throw ProtocolError("frame 1: JSON larger than 1 MiB");
  try {
    // The parser configs are read with: a key given twice is refused, not last-one-wins.
    const json j = parse_json_text(frames[0], "frame 1");
    JsonFields f(j);
    // A peer sending 4.0 or "4" needs to hear what "v" is, not an integer range.
    if (f.has("v") && !j["v"].is_number_integer())
      throw ProtocolError("v: expected the protocol version as a whole number (this is version " +
                          std::to_string(kVersion) + "), found " +
                          (j["v"].is_number() ? j["v"].dump() : std::string("a JSON ") + j["v"].type_name()));
    const int64_t version = f.integer("v", INT32_MIN, INT32_MAX);
    if (version != kVersion)
      throw ProtocolError("v: unsupported protocol version " + std::to_string(version) + " (this is " +
                          std::to_string(kVersion) + ")");
    const std::string type = f.string("type", 1, 64);
    const auto rule = rules().find(type);
    if (type == "result")
      throw ProtocolError("type: 'result' is a binary frame starting with RFPX since protocol version 3, not JSON");
    if (rule == rules().end()) throw ProtocolError("type: unknown message type '" + type + "'");
    if (frames.size() != rule->second.frames)
      throw ProtocolError("'" + type + "' takes " + std::to_string(rule->second.frames) + " frame(s), got " +
                          std::to_string(frames.size()));
    Message m = rule->second.read(f, frames);
    f.finish();
    return m;
  } catch (const ProtocolError&) {
    throw;
  } catch (const InputError& e) {
    throw ProtocolError(e.what());
  }
}

std::optional<OtherVersion> other_version(const Frames& frames) {
  if (frames.empty() || is_result_frame(frames[0]) || frames[0].size() > kMaxJsonBytes) return std::nullopt;
  const json j = json::parse(frames[0], nullptr, /*allow_exceptions=*/false);
  if (!j.is_object() || !j.contains("v") || !j["v"].is_number_integer() || !j.contains("type") ||
      !j["type"].is_string())
    return std::nullopt;
  // A version beyond int64 is no version this one speaks either.
  const int64_t v = j["v"].is_number_unsigned() && j["v"].get<uint64_t>() > uint64_t{INT64_MAX}
                        ? INT64_MAX
                        : j["v"].get<int64_t>();
  if (v == kVersion) return std::nullopt;
  OtherVersion other{v, ""};
  if (j["type"] == "reregister" && j.contains("reason") && j["reason"].is_string())
    other.reason = j["reason"].get<std::string>();
  return other;
}

uint64_t fnv1a64(std::string_view bytes) {
  uint64_t h = 0xcbf29ce484222325ull;  // FNV-1a offset basis and prime (Fowler, Noll, Vo)
  for (unsigned char c : bytes) {
    h ^= c;
    h *= 0x100000001b3ull;
  }
  return h;
}

std::string hash_hex(uint64_t hash) {
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(hash));
  return buf;
}

}  // namespace rayfarm::protocol
