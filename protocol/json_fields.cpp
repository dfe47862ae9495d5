// Strict typed JSON field access; see json_fields.h.
#include "protocol/json_fields.h"

#include <cmath>
#include <cstdio>

#include "tracer/text_file.h"

namespace rayfarm {

std::string found_value(const nlohmann::json& value) { return ", found " + json_excerpt(value); }

JsonFields::JsonFields(const nlohmann::json& object, std::string path)
    : json_(object), path_(std::move(path)) {
  if (!json_.is_object())
    throw InputError((path_.empty() ? std::string("document") : path_) + ": expected a JSON object" +
                     found_value(json_));
}

std::string JsonFields::key_path(const std::string& key) const {
  return path_.empty() ? key : path_ + "." + key;
}

void JsonFields::fail(const std::string& key, const std::string& what) const {
  throw InputError(key_path(key) + ": " + what);
}

bool JsonFields::has(const std::string& key) const { return json_.contains(key); }

const nlohmann::json& JsonFields::get(const std::string& key) {
  auto it = json_.find(key);
  if (it == json_.end()) fail(key, "missing");
  used_.insert(key);
  return *it;
}

int64_t JsonFields::integer(const std::string& key, int64_t lo, int64_t hi) {
  const auto& v = get(key);
  const std::string want =
      "expected an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]" + found_value(v);
  if (v.is_number_unsigned()) {
    const uint64_t u = v.get<uint64_t>();
    if (u > static_cast<uint64_t>(INT64_MAX) || static_cast<int64_t>(u) > hi || static_cast<int64_t>(u) < lo)
      fail(key, want);
    return static_cast<int64_t>(u);
  }
  if (!v.is_number_integer()) fail(key, want);
  const int64_t i = v.get<int64_t>();
  if (i < lo || i > hi) fail(key, want);
  return i;
}

uint64_t JsonFields::unsigned64(const std::string& key, uint64_t hi) {
  const auto& v = get(key);
  const std::string want = "expected an unsigned integer <= " + std::to_string(hi) + found_value(v);
  if (v.is_number_unsigned()) {
    const uint64_t u = v.get<uint64_t>();
    if (u > hi) fail(key, want);
    return u;
  }
  if (v.is_number_integer() && v.get<int64_t>() >= 0 && static_cast<uint64_t>(v.get<int64_t>()) <= hi)
    return static_cast<uint64_t>(v.get<int64_t>());
  fail(key, want);
}

double JsonFields::number(const std::string& key, double lo, double hi) {
  const auto& v = get(key);
  char want[96];
  std::snprintf(want, sizeof want, "expected a number in [%g, %g]", lo, hi);
  if (!v.is_number()) fail(key, want + found_value(v));
  const double d = v.get<double>();
  if (!std::isfinite(d) || d < lo || d > hi) fail(key, want + found_value(v));
  return d;
}

bool JsonFields::boolean(const std::string& key) {
  const auto& v = get(key);
  if (!v.is_boolean()) fail(key, "expected true or false" + found_value(v));
  return v.get<bool>();
}

std::string JsonFields::string(const std::string& key, size_t min_len, size_t max_len) {
  const auto& v = get(key);
  if (!v.is_string()) fail(key, "expected a string" + found_value(v));
  std::string s = v.get<std::string>();
  if (s.size() < min_len || s.size() > max_len)
    fail(key, "expected a string of " + std::to_string(min_len) + ".." + std::to_string(max_len) + " bytes, found " +
                  std::to_string(s.size()) + " bytes");
  return s;
}

JsonFields JsonFields::object(const std::string& key) {
  const auto& v = get(key);
  if (!v.is_object()) fail(key, "expected a JSON object" + found_value(v));
  return JsonFields(v, key_path(key));
}

const nlohmann::json& JsonFields::array(const std::string& key, size_t min_size, size_t max_size) {
  const auto& v = get(key);
  if (!v.is_array() || v.size() < min_size || v.size() > max_size)
    fail(key, "expected an array of " + std::to_string(min_size) + ".." + std::to_string(max_size) + " elements" +
                  (v.is_array() ? ", found " + std::to_string(v.size()) : found_value(v)));
  return v;
}

void JsonFields::read(const std::string& key, int& out, int lo, int hi) {
  if (has(key)) out = static_cast<int>(integer(key, lo, hi));
}
void JsonFields::read(const std::string& key, double& out, double lo, double hi) {
  if (has(key)) out = number(key, lo, hi);
}
void JsonFields::read(const std::string& key, bool& out) {
  if (has(key)) out = boolean(key);
}
void JsonFields::read(const std::string& key, std::string& out, size_t max_len) {
  if (has(key)) out = string(key, 0, max_len);
}

void JsonFields::finish() const {
  // Cut: the key is the sender's, and a key of a megabyte (a message of the
  // 1 MiB limit, a job's body) was quoted whole, into the broker's log a few
  // times a second and into an API answer.
  for (auto it = json_.begin(); it != json_.end(); ++it)
    if (!used_.count(it.key())) fail(quoted_excerpt(it.key()), "unknown key");
}

}  // namespace rayfarm
