// libFuzzer target: broker.json (broker/broker_config.h), from text. A config
// that loads must also give a task size for any legal worker weight.
#include "broker/broker_config.h"
#include "fuzz/config_fuzz.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return rayfarm::fuzz::check_config_input(data, size, "broker.json", [](const std::string& text, const std::string& name) {
    const rayfarm::BrokerConfig c = rayfarm::parse_broker_config(text, name);
    for (const double weight : {1e-6, 21.0, 1e6}) {
      const int rows = rayfarm::task_rows_for(c, weight);
      if (rows < 1 || rows > 65536) rayfarm::fuzz::fail("task_rows_for out of [1, 65536]");
    }
  });
}
