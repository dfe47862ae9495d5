// Strict JSON config files; see config_file.h.
#include "protocol/config_file.h"

#include <filesystem>

#include "tracer/error.h"
#include "tracer/text_file.h"

namespace rayfarm {

namespace {

void read_config_json(const nlohmann::json& j, const std::string& name,
                      const std::function<void(JsonFields&)>& read_fields) {
  try {
    JsonFields fields(j);
    read_fields(fields);
    fields.finish();
  } catch (const InputError& e) {
    throw InputError(name + ": " + e.what());
  }
}

}  // namespace

void read_config_file(const std::string& path, const std::function<void(JsonFields&)>& read_fields) {
  read_config_json(read_json_file(path, kMaxConfigBytes), path, read_fields);
}

void read_config_text(const std::string& text, const std::string& name,
                      const std::function<void(JsonFields&)>& read_fields) {
  read_config_json(parse_json_text(text, name), name, read_fields);
}

void resolve_beside_config(const std::string& config_path, std::initializer_list<std::string*> paths) {
  const std::filesystem::path dir = std::filesystem::path(config_path).parent_path();
  for (std::string* p : paths)
    if (!p->empty() && std::filesystem::path(*p).is_relative()) *p = (dir / *p).string();
}

}  // namespace rayfarm
