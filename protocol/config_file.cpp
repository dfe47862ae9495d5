// Strict JSON config files; see config_file.h.
#include "protocol/config_file.h"

#include "tracer/error.h"
#include "tracer/text_file.h"

namespace rayfarm {

void read_config_file(const std::string& path, const std::function<void(JsonFields&)>& read_fields) {
  const nlohmann::json j = read_json_file(path, kMaxConfigBytes);
  try {
    JsonFields fields(j);
    read_fields(fields);
    fields.finish();
  } catch (const InputError& e) {
    throw InputError(path + ": " + e.what());
  }
}

}  // namespace rayfarm
