// The RFP/3 codec: Message <-> frames (protocol/SPEC.md). A frame is a byte
// string; the transport (protocol/transport.h) moves frames over ZeroMQ. decode()
// trusts nothing: frame counts, JSON keys and types, ranges, payload sizes and
// the scene hash are all checked, and a failure names the offending field.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "protocol/messages.h"
#include "tracer/error.h"

namespace rayfarm::protocol {

using Frames = std::vector<std::string>;

// A peer sent something RFP/3 does not allow. what() is the reason.
struct ProtocolError : InputError {
  using InputError::InputError;
};

// A `result` whose header names a task (job id in range, attempt >= 1) but
// that fails after that: its rows, pixels, timings, length or a pixel value.
// It is still rejected whole, but the task it names is kept: a broker can
// then requeue that task at once when the sender holds that attempt
// (protocol/SPEC.md, rule 4) instead of leaving it held until the worker is
// lost. Nothing the header says is trusted beyond these three numbers.
struct ResultContentError : ProtocolError {
  ResultContentError(const std::string& what, uint64_t job_, uint32_t task_, uint32_t attempt_)
      : ProtocolError(what), job(job_), task(task_), attempt(attempt_) {}
  uint64_t job;
  uint32_t task, attempt;
};

Frames encode(const Message& message);
Message decode(const Frames& frames);

// A JSON message of another protocol version: the version its "v" names and,
// for a refusal (`reregister`), the reason given. Only the envelope ("v",
// "type", "reason") is read, which every version has kept; nullopt for a
// message of this version or one without that envelope.
struct OtherVersion {
  int64_t version = 0;
  std::string reason;
};
std::optional<OtherVersion> other_version(const Frames& frames);

// 64-bit FNV-1a: the scene's content identity (job announcements, worker cache).
uint64_t fnv1a64(std::string_view bytes);
std::string hash_hex(uint64_t hash);  // 16 lowercase hex digits

}  // namespace rayfarm::protocol
