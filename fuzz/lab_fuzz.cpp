// libFuzzer target: lab JSON (worker/lab.h), from text. Worker configs named
// by the lab come from a small in-memory set instead of the file system (the
// file-reading side is tested on its own), so every input is pure text: an
// entry's "config" resolves against fuzz/labs/ and may name ../workers/ok.json
// (loads), ../workers/bad.json (an error inside the worker config) or anything
// else (cannot open).
#include <map>

#include "fuzz/config_fuzz.h"
#include "tracer/error.h"
#include "worker/lab.h"

using namespace rayfarm;

namespace {

WorkerConfig load_in_memory(const std::string& path) {
  static const std::map<std::string, std::string> files = {
      {"fuzz/labs/../workers/ok.json", R"({"name": "ok", "weight": 21.0, "threads": 1, "throttle": 2.5})"},
      {"fuzz/labs/../workers/bad.json", R"({"weight": 21.0, "heartbeat": {"intervl_ms": 100}})"},
  };
  const auto it = files.find(path);
  if (it == files.end()) throw InputError(path + ": cannot open (not in the fuzz set)");
  return parse_worker_config(it->second, path);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return fuzz::check_config_input(data, size, "fuzz/labs/lab.json", [](const std::string& text, const std::string& name) {
    const Lab lab = parse_lab(text, name, load_in_memory);
    if (lab.types.empty()) fuzz::fail("a lab without machines loaded");
    (void)lab.machine_count();
  });
}
