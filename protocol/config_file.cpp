// Strict JSON config files; see config_file.h.
#include "protocol/config_file.h"

#include <fstream>
#include <sstream>

#include "tracer/error.h"

namespace rayfarm {

void read_config_file(const std::string& path, const std::function<void(JsonFields&)>& read_fields) {
  std::ifstream in(path);
  if (!in) throw InputError(path + ": cannot open config file");
  std::stringstream text;
  text << in.rdbuf();
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(text.str());
  } catch (const nlohmann::json::parse_error& e) {
    throw InputError(path + ": invalid JSON: " + e.what());
  }
  try {
    JsonFields fields(j);
    read_fields(fields);
    fields.finish();
  } catch (const InputError& e) {
    throw InputError(path + ": " + e.what());
  }
}

}  // namespace rayfarm
