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
