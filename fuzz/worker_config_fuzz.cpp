// libFuzzer target: worker config JSON (worker/worker_config.h), from text.
#include "fuzz/config_fuzz.h"
#include "worker/worker_config.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return rayfarm::fuzz::check_config_input(data, size, "worker.json", rayfarm::parse_worker_config);
}
