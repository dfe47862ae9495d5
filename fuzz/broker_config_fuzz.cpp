// libFuzzer target: broker.json (broker/broker_config.h), from text. A config
// that loads must also give a task size for any legal worker weight: within
// [1, max_task_rows], or 0 exactly when the adaptive policy sizes each task at
// dispatch.
#include <algorithm>

#include "broker/broker_config.h"
#include "fuzz/config_fuzz.h"

using namespace rayfarm;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return fuzz::check_config_input(data, size, "broker.json", [](const std::string& text, const std::string& name) {
    const BrokerConfig c = parse_broker_config(text, name);
    const bool adaptive = c.policy == PolicyKind::adaptive;
    for (const double weight : {1e-6, 21.0, 1e6}) {
      const int rows = task_rows_for(c, weight);
      if (adaptive ? rows != 0 : rows < 1 || rows > std::max(1, c.max_task_rows))
        fuzz::fail("task_rows_for(" + std::to_string(weight) + ") = " + std::to_string(rows));
    }
  });
}
