// RFP/3 codec tests: every message type survives a round trip, and every way a
// peer can break the grammar of protocol/SPEC.md is rejected with a reason.
#include <doctest/doctest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <limits>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "protocol/codec.h"
#include "tracer/log_text.h"

using namespace rayfarm;
using namespace rayfarm::protocol;
using nlohmann::json;

namespace {

// The rejection reason, or "" when the frames decode.
std::string reject_reason(const Frames& frames) {
  try {
    decode(frames);
    return "";
  } catch (const ProtocolError& e) {
    return e.what();
  }
}

bool rejected_for(const Frames& frames, const std::string& needle) {
  const std::string why = reject_reason(frames);
  INFO("reason: '" << why << "' expected to mention '" << needle << "'");
  return !why.empty() && why.find(needle) != std::string::npos;
}

TaskResult sample_result(int y0 = 3, int y1 = 5, int width = 4) {
  TaskResult r;
  r.job = 42;
  r.task = 7;
  r.attempt = 2;
  r.y0 = y0;
  r.y1 = y1;
  r.width = width;
  r.x0 = 0;
  r.x1 = width;
  r.render_s = 0.25;
  r.throttle_s = 0.5;
  r.stats.eye = 8;
  r.stats.eye_hit = 6;
  r.stats.shadow = 18;
  r.stats.reflection = 3;
  r.stats.refraction = 1;
  r.stats.non_finite = 2;
  r.rgb.resize(static_cast<size_t>(y1 - y0) * width * 3);
  for (size_t i = 0; i < r.rgb.size(); ++i) r.rgb[i] = 0.01f * static_cast<float>(i) + 1e-7f;
  return r;
}

JobSpec sample_job() {
  JobSpec j;
  j.job = 9007199254740991ull;  // the largest id allowed
  j.scene_text = "b 0 0 0\nv\nfrom 0 0 1\nat 0 0 0\nup 0 1 0\nangle 45\nhither 1\nresolution 8 8\n";
  j.scene_hash = fnv1a64(j.scene_text);
  j.scene_name = "tiny.nff";
  j.settings.width = 64;
  j.settings.height = 48;
  j.settings.spp = 4;
  j.settings.max_depth = 5;
  j.settings.seed = 0xfedcba9876543210ull;
  j.settings.adaptive_contrast = 0.125;
  j.settings.cutoff = 0.001;
  j.settings.robust_bvh = true;
  return j;
}

// Re-encodes the JSON frame of `frames` after `edit`.
Frames with_json(Frames frames, const std::function<void(json&)>& edit) {
  json j = json::parse(frames[0]);
  edit(j);
  frames[0] = j.dump();
  return frames;
}

template <class T> T round_trip(const T& m) {
  const Message back = decode(encode(Message{m}));
  REQUIRE(std::holds_alternative<T>(back));
  return std::get<T>(back);
}

}  // namespace

TEST_CASE("protocol: FNV-1a 64 matches the published test vectors") {
  CHECK(fnv1a64("") == 0xcbf29ce484222325ull);
  CHECK(fnv1a64("a") == 0xaf63dc4c8601ec8cull);
  CHECK(fnv1a64("foobar") == 0x85944171f73967e8ull);
  CHECK(hash_hex(0xaf63dc4c8601ec8cull) == "af63dc4c8601ec8c");
}

TEST_CASE("protocol: every message type round-trips") {
  const Welcome w = round_trip(Welcome{250, 4, 5556, 17});
  CHECK(w.heartbeat_ms == 250);
  CHECK(w.liveness == 4);
  CHECK(w.pub_port == 5556);
  CHECK(w.job == 17);
  CHECK(round_trip(Heartbeat{0}).job == 0);
  CHECK(round_trip(Heartbeat{5}).job == 5);

  const JobSpec j = sample_job();
  const JobSpec jb = round_trip(j);
  CHECK(jb.job == j.job);
  CHECK(jb.scene_hash == j.scene_hash);
  CHECK(jb.scene_name == j.scene_name);
  CHECK(jb.scene_text == j.scene_text);
  CHECK(jb.settings.width == 64);
  CHECK(jb.settings.height == 48);
  CHECK(jb.settings.spp == 4);
  CHECK(jb.settings.max_depth == 5);
  CHECK(jb.settings.seed == j.settings.seed);
  CHECK(jb.settings.adaptive_contrast == 0.125);
  CHECK(jb.settings.cutoff == 0.001);
  CHECK(jb.settings.robust_bvh);

  const TaskAssign t = round_trip(TaskAssign{3, 11, 2, 10, 13, 0, 64});
  CHECK(t.job == 3);
  CHECK(t.task == 11);
  CHECK(t.attempt == 2);
  CHECK(t.y0 == 10);
  CHECK(t.y1 == 13);
  CHECK(t.x0 == 0);
  CHECK(t.x1 == 64);
  const TaskAssign span = round_trip(TaskAssign{3, 12, 1, 20, 21, 16, 48});
  CHECK(span.y0 == 20);
  CHECK(span.y1 == 21);
  CHECK(span.x0 == 16);
  CHECK(span.x1 == 48);
  CHECK(round_trip(Reregister{"unknown worker"}).reason == "unknown worker");
  round_trip(Shutdown{});
  round_trip(Bye{});
  CHECK(round_trip(JobDone{8}).job == 8);
  const JobFailed jf = round_trip(JobFailed{8, FailureScope::worker, "out of memory"});
  CHECK(jf.job == 8);
  CHECK(jf.scope == FailureScope::worker);
  CHECK(jf.reason == "out of memory");
  CHECK(round_trip(JobFailed{9, FailureScope::job, "t.nff:3: bad"}).scope == FailureScope::job);
  CHECK(round_trip(FetchJob{8}).job == 8);
  const JobReady jr = round_trip(JobReady{8, 1.5});
  CHECK(jr.job == 8);
  CHECK(jr.init_s == 1.5);

  const Ready r = round_trip(Ready{"sun-ssc-07", 21.0, 4, 3, 500, 2.87});
  CHECK(r.name == "sun-ssc-07");
  CHECK(r.weight == 21.0);
  CHECK(r.threads == 4);
  CHECK(r.credit == 3);
  CHECK(r.heartbeat_ms == 500);
  CHECK(r.throttle == 2.87);

  const TaskResult res = sample_result();
  const TaskResult rb = round_trip(res);
  CHECK(rb.job == 42);
  CHECK(rb.task == 7);
  CHECK(rb.attempt == 2);
  CHECK(rb.y0 == 3);
  CHECK(rb.y1 == 5);
  CHECK(rb.width == 4);
  CHECK(rb.render_s == 0.25);
  CHECK(rb.throttle_s == 0.5);
  CHECK(rb.stats.eye == 8);
  CHECK(rb.stats.eye_hit == 6);
  CHECK(rb.stats.shadow == 18);
  CHECK(rb.stats.reflection == 3);
  CHECK(rb.stats.refraction == 1);
  CHECK(rb.stats.non_finite == 2);
  REQUIRE(rb.rgb.size() == res.rgb.size());
  CHECK(std::memcmp(rb.rgb.data(), res.rgb.data(), res.rgb.size() * 4) == 0);
}

TEST_CASE("protocol: a result is one binary frame with the fixed little-endian layout") {
  const Frames f = encode(Message{sample_result(3, 5, 4)});
  REQUIRE(f.size() == 1);
  const std::string& p = f[0];
  CHECK(p.size() == 112 + 2 * 4 * 3 * 4);
  CHECK(p.substr(0, 4) == "RFPX");
  auto u32 = [&](size_t at) {
    return uint32_t(uint8_t(p[at])) | uint32_t(uint8_t(p[at + 1])) << 8 | uint32_t(uint8_t(p[at + 2])) << 16 |
           uint32_t(uint8_t(p[at + 3])) << 24;
  };
  auto u64 = [&](size_t at) { return uint64_t{u32(at)} | uint64_t{u32(at + 4)} << 32; };
  auto f64 = [&](size_t at) {
    const uint64_t bits = u64(at);
    double d;
    std::memcpy(&d, &bits, 8);
    return d;
  };
  CHECK((u32(4) & 0xffff) == 3);   // layout version
  CHECK((u32(4) >> 16) == 112);    // header size
  CHECK(u64(8) == 42);             // job
  CHECK(u32(16) == 7);             // task
  CHECK(u32(20) == 2);             // attempt
  CHECK(u32(24) == 3);             // y0
  CHECK(u32(28) == 5);             // y1
  CHECK(u32(32) == 4);             // width
  CHECK(u32(36) == 0);             // reserved
  CHECK(f64(40) == 0.25);          // render_s
  CHECK(f64(48) == 0.5);           // throttle_s
  CHECK(u64(56) == 8);             // eye
  CHECK(u64(64) == 6);             // eye_hit
  CHECK(u64(72) == 18);            // shadow
  CHECK(u64(80) == 3);             // reflection
  CHECK(u64(88) == 1);             // refraction
  CHECK(u64(96) == 2);             // non_finite
  CHECK(u32(104) == 0);            // x0
  CHECK(u32(108) == 4);            // x1
  float first;
  std::memcpy(&first, &p[112], 4);
  CHECK(first == sample_result().rgb[0]);
}

TEST_CASE("protocol: malformed frame sequences are rejected with a reason") {
  const Frames task = encode(Message{TaskAssign{3, 1, 1, 0, 1, 0, 8}});
  CHECK(rejected_for({}, "expected 1 or 2 frames, got 0"));
  CHECK(rejected_for({task[0], "x", "y"}, "got 3"));
  CHECK(rejected_for({task[0], "extra"}, "'task' takes 1 frame(s), got 2"));
  CHECK(rejected_for({"{\"v\":1,"}, "frame 1: invalid JSON"));
  CHECK(rejected_for({"[1,2]"}, "expected a JSON object"));
  CHECK(rejected_for({std::string(kMaxJsonBytes + 1, ' ')}, "larger than 1 MiB"));
  CHECK(rejected_for(with_json(task, [](json& j) { j.erase("v"); }), "v: missing"));
  CHECK(rejected_for(with_json(task, [](json& j) { j["v"] = 1; }), "unsupported protocol version 1 (this is 4)"));
  CHECK(rejected_for(with_json(task, [](json& j) { j["type"] = "steal"; }), "unknown message type 'steal'"));
  CHECK(rejected_for(with_json(task, [](json& j) { j["typo"] = 1; }), "typo: unknown key"));
  CHECK(rejected_for(with_json(task, [](json& j) { j.erase("y1"); }), "y1: missing"));
  CHECK(rejected_for(with_json(task, [](json& j) { j["y1"] = 0; }), "y1"));
  CHECK(rejected_for(with_json(task, [](json& j) { j["y0"] = 5; j["y1"] = 5; }), "y1: must be greater than y0"));
  CHECK(rejected_for(with_json(task, [](json& j) { j["y1"] = 70000; }), "y1: expected an integer in [1, 65536]"));
  CHECK(rejected_for(with_json(task, [](json& j) { j["attempt"] = 0; }), "attempt"));
  CHECK(rejected_for(with_json(task, [](json& j) { j["job"] = 0; }), "job id >= 1"));
  CHECK(rejected_for(with_json(task, [](json& j) { j["job"] = -1; }), "job: expected an unsigned integer"));
  CHECK(rejected_for(with_json(task, [](json& j) { j["job"] = uint64_t{1} << 60; }), "job"));
  CHECK(rejected_for(with_json(task, [](json& j) { j["task"] = 1.5; }), "task: expected an integer"));
  CHECK(rejected_for(with_json(task, [](json& j) { j.erase("x1"); }), "x1: missing"));
  CHECK(rejected_for(with_json(task, [](json& j) { j["x0"] = -1; }), "x0: expected an integer in [0, 65535]"));
  CHECK(rejected_for(with_json(task, [](json& j) { j["x1"] = 70000; }), "x1: expected an integer in [1, 65536]"));
  CHECK(rejected_for(with_json(task, [](json& j) { j["x0"] = 8; j["x1"] = 8; }), "x1: must be greater than x0"));
  CHECK(rejected_for(with_json(task, [](json& j) { j["x0"] = 4; j["y1"] = 3; }), "x0: a pixel span (x0 > 0) must be one row"));
  CHECK(reject_reason(with_json(task, [](json& j) { j["x0"] = 4; })).empty());  // a span of one row
}

TEST_CASE("protocol: a version that is no whole number is refused saying what v is") {
  const Frames task = encode(Message{TaskAssign{3, 1, 1, 0, 1, 0, 8}});
  const std::string want = "v: expected the protocol version as a whole number (this is version " +
                           std::to_string(kVersion) + "), found ";
  CHECK(rejected_for(with_json(task, [](json& j) { j["v"] = 4.0; }), want + "4.0"));
  CHECK(rejected_for(with_json(task, [](json& j) { j["v"] = "1"; }), want + "a JSON string"));
}

TEST_CASE("protocol: a key given twice in one message is refused, naming the key") {
  // Last one wins would read this ready as a bye.
  CHECK(rejected_for({R"({"v":4,"type":"ready","type":"bye"})"}, "frame 1: invalid JSON: duplicate key \"type\""));
  const Frames job = encode(Message{sample_job()});
  std::string twice = job[0];
  twice.replace(twice.find("\"width\":"), 0, "\"width\":1,");
  CHECK(rejected_for({twice, job[1]}, "duplicate key \"width\""));
}

TEST_CASE("protocol: registration and job fields are range-checked") {
  const Frames ready = encode(Message{Ready{"w", 21.0, 0, 2, 1000, 1.0}});
  CHECK(reject_reason(ready).empty());
  CHECK(rejected_for(with_json(ready, [](json& j) { j["name"] = ""; }), "name"));
  CHECK(rejected_for(with_json(ready, [](json& j) { j["name"] = std::string(129, 'n'); }), "name"));
  CHECK(rejected_for(with_json(ready, [](json& j) { j["weight"] = 0; }), "weight"));
  CHECK(rejected_for(with_json(ready, [](json& j) { j["weight"] = -3; }), "weight"));
  CHECK(rejected_for(with_json(ready, [](json& j) { j["credit"] = 0; }), "credit"));
  CHECK(rejected_for(with_json(ready, [](json& j) { j["credit"] = 1000; }), "credit"));
  CHECK(rejected_for(with_json(ready, [](json& j) { j["heartbeat_ms"] = 1; }), "heartbeat_ms"));
  CHECK(rejected_for(with_json(ready, [](json& j) { j["throttle"] = 0.5; }), "throttle"));

  const Frames job = encode(Message{sample_job()});
  CHECK(reject_reason(job).empty());
  CHECK(rejected_for({job[0], job[1] + " "}, "does not match scene_hash"));
  CHECK(rejected_for({job[0]}, "'job' takes 2 frame(s), got 1"));
  CHECK(rejected_for(with_json(job, [](json& j) { j["scene_hash"] = "XYZ0000000000000"; }), "16 lowercase hex"));
  CHECK(rejected_for(with_json(job, [](json& j) { j["settings"]["width"] = 0; }), "settings.width"));
  CHECK(rejected_for(with_json(job, [](json& j) { j["settings"]["height"] = 1 << 20; }), "settings.height"));
  CHECK(rejected_for(with_json(job, [](json& j) { j["settings"]["spp"] = -4; }), "settings.spp"));
  CHECK(rejected_for(with_json(job, [](json& j) { j["settings"]["cutoff"] = 1.5; }), "settings.cutoff"));
  CHECK(rejected_for(with_json(job, [](json& j) { j["settings"]["threads"] = 4; }), "settings.threads: unknown key"));
  CHECK(rejected_for(with_json(job, [](json& j) { j["settings"]["robust_bvh"] = 1; }), "settings.robust_bvh"));
  CHECK(rejected_for(with_json(job, [](json& j) { j["settings"].erase("seed"); }), "settings.seed: missing"));

  const Frames failed = encode(Message{JobFailed{4, FailureScope::job, "t.nff:1: bad"}});
  CHECK(reject_reason(failed).empty());
  CHECK(rejected_for(with_json(failed, [](json& j) { j["scope"] = "everyone"; }), "scope: expected"));
  CHECK(rejected_for(with_json(failed, [](json& j) { j["reason"] = ""; }), "reason"));
  CHECK(rejected_for(with_json(failed, [](json& j) { j["reason"] = std::string(4097, 'r'); }), "reason"));
  CHECK(rejected_for(with_json(failed, [](json& j) { j["job"] = 0; }), "job"));
}

TEST_CASE("protocol: a wrong value quoted in a reason is cut between characters, so JSON can carry the reason") {
  const Frames ready = encode(Message{Ready{"w", 21.0, 0, 2, 1000, 1.0}});
  // The quote's 37th byte was the first of an e-acute, cut there: the reason,
  // put in a job record or an API answer, made nlohmann::json::dump() throw.
  const std::string accented = std::string(35, 'a') + "\xc3\xa9\xc3\xa9\xc3\xa9";
  const std::string why = reject_reason(with_json(ready, [&](json& j) { j["weight"] = accented; }));
  CHECK(why.find("weight: expected a number in [0, 1e+06], found \"" + accented.substr(0, 39) + "...") !=
        std::string::npos);
  CHECK_NOTHROW((void)json(why).dump());
}

TEST_CASE("protocol: an unknown key of a megabyte is named by its start, not quoted whole in the reason") {
  const Frames ready = encode(Message{Ready{"w", 21.0, 0, 2, 1000, 1.0}});
  const std::string key = "\xc3\xa9" + std::string(1000000, 'k');
  const std::string why = reject_reason(with_json(ready, [&](json& j) { j[key] = 1; }));
  CHECK(why == key.substr(0, 80) + "...: unknown key");
}

TEST_CASE("protocol: result frames with wrong fields, sizes or values are rejected naming the field") {
  const Frames good = encode(Message{sample_result(3, 5, 4)});
  CHECK(reject_reason(good).empty());
  const std::string& p = good[0];
  auto patch = [&](size_t at, auto v) {
    std::string q = p;
    std::memcpy(&q[at], &v, sizeof v);
    return Frames{q};
  };
  CHECK(rejected_for({p, "extra"}, "'result' takes 1 frame, got 2"));
  CHECK(rejected_for({p.substr(0, 20)}, "shorter than the 112-byte header"));
  CHECK(rejected_for({p.substr(0, p.size() - 4)}, "rows * (x1 - x0) * 3 * 4 + 112"));  // truncated
  CHECK(rejected_for({p + "    "}, "rows * (x1 - x0) * 3 * 4 + 112"));                // trailing bytes
  CHECK(rejected_for({"XXXX" + p.substr(4)}, "frame 1: invalid JSON"));             // not a result frame at all
  CHECK(rejected_for(patch(4, uint16_t{2}), "result.version: unsupported result layout 2"));
  CHECK(rejected_for(patch(6, uint16_t{40}), "result.header_size"));
  // A small frame claiming a huge image: the length check fails before any allocation.
  CHECK(rejected_for(patch(28, uint32_t{65536}), "rows * (x1 - x0) * 3 * 4 + 112"));
  CHECK(rejected_for(patch(32, uint32_t{0}), "result.width: width 0 out of range"));
  CHECK(rejected_for(patch(32, uint32_t{70000}), "result.width: width 70000 out of range"));
  CHECK(rejected_for(patch(28, uint32_t{70000}), "out of range"));
  CHECK(rejected_for(patch(24, uint32_t{5}), "rows [5, 5) out of range"));
  CHECK(rejected_for(patch(20, uint32_t{0}), "result.attempt: must be >= 1"));
  CHECK(rejected_for(patch(8, uint64_t{0}), "result.job"));
  CHECK(rejected_for(patch(8, uint64_t{1} << 60), "result.job"));
  CHECK(rejected_for(patch(36, uint32_t{1}), "result.reserved"));
  CHECK(rejected_for(patch(40, -0.1), "result.render_s"));
  CHECK(rejected_for(patch(40, std::numeric_limits<double>::quiet_NaN()), "result.render_s"));
  CHECK(rejected_for(patch(48, std::numeric_limits<double>::infinity()), "result.throttle_s"));
  CHECK(rejected_for(patch(48, 2e9), "result.throttle_s"));
  CHECK(rejected_for(patch(112 + 8, std::numeric_limits<float>::quiet_NaN()), "non-finite"));
  // Pixels: x0 < x1 <= width, and a span (not the whole row) is one row.
  CHECK(rejected_for(patch(108, uint32_t{5}), "result.x0/x1: pixels [0, 5) out of range for width 4"));
  CHECK(rejected_for(patch(104, uint32_t{4}), "result.x0/x1: pixels [4, 4) out of range for width 4"));
  CHECK(rejected_for(patch(104, UINT32_MAX), "result.x0/x1: pixels [65537, 4) out of range"));
  CHECK(rejected_for(patch(108, uint32_t{2}), "result.x0/x1: a span of pixels [0, 2) must be one row, not rows [3, 5)"));
  // A span of one row round-trips, its frame sized by the span.
  TaskResult span = sample_result(3, 4, 8);
  span.x0 = 2;
  span.x1 = 5;
  span.rgb.assign(3 * 3, 0.5f);
  span.rgb[4] = 0.75f;
  const Frames span_frame = encode(Message{span});
  CHECK(span_frame[0].size() == 112 + 3 * 12);
  const TaskResult back = std::get<TaskResult>(decode(span_frame));
  CHECK(back.x0 == 2);
  CHECK(back.x1 == 5);
  CHECK(back.width == 8);
  CHECK(back.rgb == span.rgb);
  // Ray counts are any unsigned 64-bit values.
  const Message big = decode(patch(56, UINT64_MAX));
  CHECK(std::get<TaskResult>(big).stats.eye == UINT64_MAX);
  // The RFP/2 encoding (JSON frame + pixel frame) is refused with a reason.
  CHECK(rejected_for({R"({"v":2,"type":"result","render_s":0,"throttle_s":0,"stats":{}})", p},
                     "unsupported protocol version 2"));
  CHECK(rejected_for({R"({"v":4,"type":"result"})"}, "binary frame starting with RFPX"));
}

TEST_CASE("protocol: a result rejected after naming its task keeps that task for the broker to requeue") {
  // The broker requeues that task when the sender holds it (protocol/SPEC.md,
  // rule 4); the decoder kept only a reason, so the task stayed held.
  const std::string p = encode(Message{sample_result(3, 5, 4)})[0];
  auto patch = [&](size_t at, auto v) {
    std::string q = p;
    std::memcpy(&q[at], &v, sizeof v);
    return Frames{q};
  };
  // Content: rows, pixels, timings, length, pixel values.
  const std::vector<Frames> content = {patch(112 + 8, std::numeric_limits<float>::quiet_NaN()),
                                       patch(112, std::numeric_limits<float>::infinity()),
                                       {p.substr(0, p.size() - 12)},
                                       {p + "    "},
                                       patch(24, uint32_t{5}),
                                       patch(32, uint32_t{0}),
                                       patch(108, uint32_t{5}),
                                       patch(36, uint32_t{1}),
                                       patch(40, -0.1)};
  for (const Frames& f : content) {
    try {
      decode(f);
      FAIL("decoded a damaged result");
    } catch (const ResultContentError& e) {
      INFO(e.what());
      CHECK(e.job == 42);
      CHECK(e.task == 7);
      CHECK(e.attempt == 2);
    }
  }
  // Before the task is read, or when the header's task is not one: no task to keep.
  const std::vector<Frames> header = {{p.substr(0, 20)}, patch(4, uint16_t{2}), patch(6, uint16_t{40}),
                                      patch(8, uint64_t{0}), patch(20, uint32_t{0})};
  for (const Frames& f : header) {
    try {
      decode(f);
      FAIL("decoded a damaged result");
    } catch (const ResultContentError& e) {
      FAIL("kept a task for: " << e.what());
    } catch (const ProtocolError&) {
    }
  }
}

TEST_CASE("protocol: randomly damaged messages decode or throw ProtocolError, nothing else") {
  // Fixed-seed fuzzing: flip bytes, cut and extend every frame of every message
  // type; the decoder must never crash, hang, or throw anything but ProtocolError.
  const std::vector<Frames> valid = {
      encode(Message{Welcome{1000, 3, 5556, 4}}), encode(Message{Heartbeat{4}}), encode(Message{sample_job()}),
      encode(Message{TaskAssign{4, 1, 1, 0, 2, 0, 8}}), encode(Message{Reregister{"x"}}), encode(Message{Shutdown{}}),
      encode(Message{Ready{"w", 21.0, 0, 2, 1000, 1.0}}), encode(Message{FetchJob{4}}),
      encode(Message{JobReady{4, 0.5}}), encode(Message{sample_result()}), encode(Message{Bye{}}),
      encode(Message{JobDone{4}}), encode(Message{JobFailed{4, FailureScope::job, "t.nff:1: bad"}}),
  };
  std::mt19937 rng(20260122);
  int accepted = 0, rejected = 0;
  for (int round = 0; round < 20000; ++round) {
    Frames f = valid[rng() % valid.size()];
    std::string& frame = f[rng() % f.size()];
    switch (rng() % 4) {
      case 0:  // flip a byte
        if (!frame.empty()) frame[rng() % frame.size()] ^= static_cast<char>(1 + rng() % 255);
        break;
      case 1:  // cut
        frame.resize(frame.empty() ? 0 : rng() % frame.size());
        break;
      case 2:  // extend
        frame.append(1 + rng() % 16, static_cast<char>(rng()));
        break;
      default:  // drop or add a frame
        if (f.size() > 1 || rng() % 2) f.pop_back(); else f.push_back("x");
    }
    try {
      decode(f);
      ++accepted;
    } catch (const ProtocolError&) {
      ++rejected;
    }
  }
  CHECK(rejected > 10000);  // most damage is caught...
  CHECK(accepted > 0);      // ...some is harmless (a digit changed within range)
}

TEST_CASE("protocol: log text escapes control characters and the backslash, so no two texts read alike") {
  CHECK(escape_control_characters("w\nx\r\t\x1b[2J") == "w\\nx\\r\\t\\x1b[2J");
  CHECK(escape_control_characters("c1 \xc2\x9b end") == "c1 \\u009b end");
  CHECK(escape_control_characters("caf\xc3\xa9") == "caf\xc3\xa9");  // other UTF-8 stays
  // A name with a real newline and one that spells the escape out.
  const std::string real = escape_control_characters("a\nb"), spelled = escape_control_characters("a\\nb");
  CHECK(real == "a\\nb");
  CHECK(spelled == "a\\\\nb");
  CHECK(real != spelled);
}

TEST_CASE("protocol: log text escapes the bidi controls and line separators, which make a line read otherwise") {
  // "w\u202egnp.exe" was shown "wexe.png"; U+2028 broke the line in a viewer.
  CHECK(escape_control_characters("w\xe2\x80\xae" "gnp.exe") == "w\\u202egnp.exe");
  CHECK(escape_control_characters("a\xe2\x80\xa8" "b\xe2\x80\xa9" "c") == "a\\u2028b\\u2029c");
  // Every embedding, override and isolate: U+202A..U+202E, U+2066..U+2069.
  for (const unsigned cp : {0x202au, 0x202bu, 0x202cu, 0x202du, 0x202eu, 0x2066u, 0x2067u, 0x2068u, 0x2069u}) {
    CAPTURE(cp);
    const std::string utf8 = {char(0xe0 | cp >> 12), char(0x80 | (cp >> 6 & 0x3f)), char(0x80 | (cp & 0x3f))};
    char escaped[8];
    std::snprintf(escaped, sizeof escaped, "\\u%04x", cp);
    CHECK(escape_control_characters("x" + utf8 + "y") == "x" + std::string(escaped) + "y");
  }
  // Their neighbours are printable and stay: U+2027, U+202F (a narrow no-break space), U+2065.
  const std::string kept = "\xe2\x80\xa7 \xe2\x80\xaf \xe2\x81\xa5";
  CHECK(escape_control_characters(kept) == kept);
}

TEST_CASE("protocol: log text escapes the bidi marks and the zero-width characters, unseen in a line") {
  // "worker\u200b1" printed as "worker1", a name it is not; U+200F turned what followed it in a right-to-left line.
  CHECK(escape_control_characters("worker\xe2\x80\x8b" "1") == "worker\\u200b1");
  CHECK(escape_control_characters("a\xe2\x80\x8f" "b\xe2\x80\x8e" "c") == "a\\u200fb\\u200ec");
  // The Arabic letter mark is two bytes (0xd8 0x9c), the byte-order mark three, anywhere in the line.
  CHECK(escape_control_characters("x\xd8\x9c" "y") == "x\\u061cy");
  CHECK(escape_control_characters("\xef\xbb\xbf" "name\xef\xbb\xbf") == "\\ufeffname\\ufeff");
  // Every one: U+200B..U+200F, U+2060..U+2064.
  for (const unsigned cp : {0x200bu, 0x200cu, 0x200du, 0x200eu, 0x200fu, 0x2060u, 0x2061u, 0x2062u, 0x2063u, 0x2064u}) {
    CAPTURE(cp);
    const std::string utf8 = {char(0xe0 | cp >> 12), char(0x80 | (cp >> 6 & 0x3f)), char(0x80 | (cp & 0x3f))};
    char escaped[8];
    std::snprintf(escaped, sizeof escaped, "\\u%04x", cp);
    CHECK(escape_control_characters("x" + utf8 + "y") == "x" + std::string(escaped) + "y");
  }
  // Their neighbours are seen and stay: U+061B (Arabic semicolon), U+061D, U+200A (a hair space), U+2010 (a
  // hyphen), U+205F (a medium space), U+FEFC (a lam-alef) and U+FF01 (a fullwidth '!'), and Arabic and Hebrew letters.
  const std::string kept = "\xd8\x9b \xd8\x9d \xe2\x80\x8a \xe2\x80\x90 \xe2\x81\x9f \xef\xbb\xbc \xef\xbc\x81 "
                           "\xd8\xa8 \xd7\x90";
  CHECK(escape_control_characters(kept) == kept);
}

TEST_CASE("protocol: log text escapes every invisible or format character of its one table, each listed here") {
  // The soft hyphen, the Mongolian vowel separator, the deprecated format
  // characters and the tags printed as nothing; a tag spells ASCII unseen.
  const auto utf8 = [](unsigned cp) {
    if (cp < 0x800) return std::string{char(0xc0 | cp >> 6), char(0x80 | (cp & 0x3f))};
    if (cp < 0x10000)
      return std::string{char(0xe0 | cp >> 12), char(0x80 | (cp >> 6 & 0x3f)), char(0x80 | (cp & 0x3f))};
    return std::string{char(0xf0 | cp >> 18), char(0x80 | (cp >> 12 & 0x3f)), char(0x80 | (cp >> 6 & 0x3f)),
                       char(0x80 | (cp & 0x3f))};
  };
  const std::vector<std::pair<unsigned, std::string>> escaped = {
      {0x00ad, "\\u00ad"},     {0x061c, "\\u061c"},     {0x180e, "\\u180e"},     {0x200b, "\\u200b"},
      {0x200c, "\\u200c"},     {0x200d, "\\u200d"},     {0x200e, "\\u200e"},     {0x200f, "\\u200f"},
      {0x2028, "\\u2028"},     {0x2029, "\\u2029"},     {0x202a, "\\u202a"},     {0x202b, "\\u202b"},
      {0x202c, "\\u202c"},     {0x202d, "\\u202d"},     {0x202e, "\\u202e"},     {0x2060, "\\u2060"},
      {0x2061, "\\u2061"},     {0x2062, "\\u2062"},     {0x2063, "\\u2063"},     {0x2064, "\\u2064"},
      {0x2066, "\\u2066"},     {0x2067, "\\u2067"},     {0x2068, "\\u2068"},     {0x2069, "\\u2069"},
      {0x206a, "\\u206a"},     {0x206b, "\\u206b"},     {0x206c, "\\u206c"},     {0x206d, "\\u206d"},
      {0x206e, "\\u206e"},     {0x206f, "\\u206f"},     {0xfeff, "\\ufeff"},     {0xe0000, "\\U000e0000"},
      {0xe0001, "\\U000e0001"}, {0xe0041, "\\U000e0041"}, {0xe007f, "\\U000e007f"},
  };
  for (const auto& [cp, escape] : escaped) {
    CAPTURE(cp);
    CHECK(escape_control_characters("x" + utf8(cp) + "y") == "x" + escape + "y");
  }
  // "worker1" in tags after a name: unseen, and now eight digits each, not four and a digit to misread.
  CHECK(escape_control_characters("w" + utf8(0xe0077) + utf8(0xe0031)) == "w\\U000e0077\\U000e0031");
  // Their neighbours are seen and stay: U+00AC (not sign), U+00AE, U+1810 (Mongolian digit zero), U+2070
  // (superscript zero); and other characters of four bytes, an emoji.
  std::string kept;
  for (const unsigned cp : {0x00acu, 0x00aeu, 0x1810u, 0x2070u, 0x1f600u}) kept += utf8(cp) + " ";
  CHECK(escape_control_characters(kept) == kept);
}

TEST_CASE("protocol: valid_utf8 replaces each byte that is not UTF-8 by U+FFFD and keeps UTF-8 whole") {
  CHECK(valid_utf8("sc\xe8ne.nff") == "sc\xef\xbf\xbdne.nff");
  CHECK(valid_utf8("caf\xc3") == "caf\xef\xbf\xbd");
  const std::string utf8 = "\xc3\xa9 \xe2\x82\xac \xf0\x9f\x98\x80 \x1b";
  CHECK(valid_utf8(utf8) == utf8);
  std::string every_byte;
  for (int b = 0; b < 256; ++b) every_byte += static_cast<char>(b);
  CHECK_NOTHROW((void)nlohmann::json(valid_utf8(every_byte)).dump());
}

TEST_CASE("protocol: log text escapes bytes that are not UTF-8, each as \\xNN, and keeps UTF-8 whole") {
  // Written raw, journald showed the whole line as "[blob data]".
  CHECK(escape_control_characters("last read: '\xff\xfe'") == "last read: '\\xff\\xfe'");
  CHECK(escape_control_characters("caf\xc3") == "caf\\xc3");                // cut short at the end
  CHECK(escape_control_characters("\xc3(x") == "\\xc3(x");                  // no continuation byte
  CHECK(escape_control_characters("\x80 lone") == "\\x80 lone");            // a continuation byte alone
  CHECK(escape_control_characters("\xc0\xaf") == "\\xc0\\xaf");          // an overlong '/'
  CHECK(escape_control_characters("\xed\xa0\x80") == "\\xed\\xa0\\x80");  // a UTF-16 surrogate
  CHECK(escape_control_characters("\xf4\x90\x80\x80") == "\\xf4\\x90\\x80\\x80");  // past U+10FFFF
  // Well-formed UTF-8 of every length stays as it is: é, €, U+FFFD, an emoji.
  const std::string utf8 = "\xc3\xa9 \xe2\x82\xac \xef\xbf\xbd \xf0\x9f\x98\x80";
  CHECK(escape_control_characters(utf8) == utf8);
  // Whatever goes in, what comes out is UTF-8: JSON can hold it.
  std::string every_byte;
  for (int b = 0; b < 256; ++b) every_byte += static_cast<char>(b);
  CHECK_NOTHROW(nlohmann::json(escape_control_characters(every_byte + every_byte)).dump());
}
