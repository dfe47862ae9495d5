// libFuzzer target: the RFP/3 decoder (protocol/codec.h) on arbitrary frames,
// every message kind including job scenes and binary result frames. The input is a
// sequence of frames, each a 4-byte little-endian length and that many bytes
// (a length past the end takes the rest), as fuzz/make_protocol_seeds writes
// them. decode() must return a Message or throw ProtocolError; a Message it
// returns must survive encode() -> decode() -> encode() unchanged, so what the
// decoder accepts is exactly what the encoder can say. A rejection that keeps
// a task (ResultContentError, which the broker requeues) keeps the one the
// frame's header names, with a job id in range and an attempt >= 1.
#include <cstddef>
#include <cstdint>
#include <cstring>

#include "fuzz/fuzz_oracle.h"
#include "protocol/codec.h"

using namespace rayfarm;
using namespace rayfarm::protocol;

namespace {

Frames split_frames(const uint8_t* data, size_t size) {
  Frames frames;
  size_t at = 0;
  while (at + 4 <= size && frames.size() < 4) {
    uint32_t len = 0;
    std::memcpy(&len, data + at, 4);  // little-endian hosts only, as the codec
    at += 4;
    const size_t n = len < size - at ? len : size - at;
    frames.emplace_back(reinterpret_cast<const char*>(data + at), n);
    at += n;
  }
  return frames;
}

void check_round_trip(const Message& m) {
  const Frames once = encode(m);
  Message again;
  try {
    again = decode(once);
  } catch (const ProtocolError& e) {
    fuzz::fail(std::string("decoder refuses the encoding of a message it accepted: ") + e.what());
  }
  if (encode(again) != once) fuzz::fail("encode(decode(encode(m))) != encode(m)");
}

void check_kept_task(const Frames& frames, const ResultContentError& e) {
  const std::string& f = frames.at(0);
  uint64_t job = 0;
  uint32_t task = 0, attempt = 0;
  std::memcpy(&job, &f.at(8), 8);
  std::memcpy(&task, &f.at(16), 4);
  std::memcpy(&attempt, &f.at(20), 4);
  if (e.job != job || e.task != task || e.attempt != attempt)
    fuzz::fail(std::string("kept a task the header does not name: ") + e.what());
  if (job == 0 || job > kMaxJobId || attempt == 0) fuzz::fail(std::string("kept an invalid task: ") + e.what());
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const Frames frames = split_frames(data, size);
  fuzz::expect_clean_error("", [&] {
    try {
      check_round_trip(decode(frames));
    } catch (const ResultContentError& e) {
      check_kept_task(frames, e);
      throw;
    }
  });
  return 0;
}
