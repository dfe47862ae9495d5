// JsonFields: strict, typed reading of one JSON object from outside (a peer's
// message or a config file). Every value is range-checked, errors name the key
// path ("heartbeat.interval_ms: expected an integer in [10, 600000]") and
// finish() rejects keys nobody read, so typos never pass silently.
#pragma once

#include <cstdint>
#include <set>
#include <string>

#include <nlohmann/json.hpp>

#include "tracer/error.h"

namespace rayfarm {

// ", found 512.0": the end of an error about a JSON value, the value as it was
// written (cut short), for checks done by hand beside JsonFields' own.
std::string found_value(const nlohmann::json& value);

class JsonFields {
 public:
  // `path` is the key path of `object` itself ("" for the root).
  JsonFields(const nlohmann::json& object, std::string path = "");

  bool has(const std::string& key) const;

  // Required fields: throw InputError when missing or out of range.
  int64_t integer(const std::string& key, int64_t lo, int64_t hi);
  uint64_t unsigned64(const std::string& key, uint64_t hi = UINT64_MAX);
  double number(const std::string& key, double lo, double hi);  // finite
  bool boolean(const std::string& key);
  std::string string(const std::string& key, size_t min_len, size_t max_len);
  JsonFields object(const std::string& key);
  // A JSON array; its elements are read with JsonFields(element, key_path("key[i]")).
  const nlohmann::json& array(const std::string& key, size_t min_size, size_t max_size);

  // Optional fields: leave `out` (its in-class default) alone when missing.
  void read(const std::string& key, int& out, int lo, int hi);
  void read(const std::string& key, double& out, double lo, double hi);
  void read(const std::string& key, bool& out);
  void read(const std::string& key, std::string& out, size_t max_len = 4096);

  // Throws for the first key that no getter asked for.
  void finish() const;

  std::string key_path(const std::string& key) const;

 private:
  const nlohmann::json& get(const std::string& key);
  [[noreturn]] void fail(const std::string& key, const std::string& what) const;

  const nlohmann::json& json_;
  std::string path_;
  std::set<std::string> used_;
};

}  // namespace rayfarm
