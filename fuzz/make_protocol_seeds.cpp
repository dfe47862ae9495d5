// Writes the protocol fuzz target's seed corpus: one small, valid encoding of
// every RFP message kind (job with a tiny scene, result with a 2x2 pixel
// payload), framed as protocol_fuzz.cpp reads them. Run again after a change to
// the wire format: make_protocol_seeds fuzz/corpus/protocol
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <string>

#include "protocol/codec.h"

using namespace rayfarm;
using namespace rayfarm::protocol;

namespace {

std::string framed(const Frames& frames) {
  std::string out;
  for (const std::string& f : frames) {
    const uint32_t len = static_cast<uint32_t>(f.size());
    out.append(reinterpret_cast<const char*>(&len), 4);  // little-endian hosts
    out += f;
  }
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: make_protocol_seeds DIR\n");
    return 2;
  }
  JobSpec job;
  job.job = 3;
  job.scene_name = "tiny.nff";
  job.scene_text = "b 0 0 0\nv\nfrom 0 0 1\nat 0 0 0\nup 0 1 0\nangle 45\nhither 1\nresolution 2 2\ns 0 0 0 1\n";
  job.scene_hash = fnv1a64(job.scene_text);
  job.settings.width = job.settings.height = 2;
  job.settings.spp = 4;

  TaskResult result;
  result.job = 3;
  result.task = 1;
  result.attempt = 2;
  result.y0 = 0;
  result.y1 = 2;
  result.width = 2;
  result.x0 = 0;
  result.x1 = 2;
  result.render_s = 0.5;
  result.stats.eye = 16;
  result.stats.shadow = 9;
  result.rgb = {0, 0.25f, 0.5f, 1, 2, 3, 0.1f, 0.2f, 0.3f, 1e-7f, 4, 5};

  const std::pair<const char*, Message> seeds[] = {
      {"welcome", Welcome{500, 3, 5556, 3}},
      {"heartbeat", Heartbeat{3}},
      {"job", job},
      {"task", TaskAssign{3, 1, 1, 0, 2, 0, 2}},
      {"reregister", Reregister{"unknown peer"}},
      {"shutdown", Shutdown{}},
      {"ready", Ready{"sun-ssc-01", 21.0, 1, 2, 1000, 2.871}},
      {"fetch_job", FetchJob{3}},
      {"job_ready", JobReady{3, 0.25}},
      {"result", result},
      {"bye", Bye{}},
      {"job_done", JobDone{3}},
      {"job_failed", JobFailed{3, FailureScope::job, "tiny.nff:9: expected 4 numbers after 's'"}},
  };
  for (const auto& [name, message] : seeds) {
    const std::string path = std::string(argv[1]) + "/" + name;
    std::ofstream(path, std::ios::binary) << framed(encode(message));
  }
  return 0;
}
