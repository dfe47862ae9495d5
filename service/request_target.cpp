// Request targets to routed paths; see request_target.h.
#include "service/request_target.h"

#include <httplib.h>

#include <algorithm>
#include <cctype>

namespace rayfarm {
namespace {

const std::string kHttpScheme = "http://";

// In any case (RFC 3986 3.1: a scheme is case-insensitive).
bool has_http_scheme(const std::string& target) {
  if (target.size() < kHttpScheme.size()) return false;
  for (size_t i = 0; i < kHttpScheme.size(); ++i)
    if (std::tolower(static_cast<unsigned char>(target[i])) != kHttpScheme[i]) return false;
  return true;
}

// A target's path as written: up to its query (a fragment is no part of a
// request target, but cut all the same).
std::string raw_path(const std::string& target, size_t from) {
  return target.substr(from, target.find_first_of("?#", from) - from);
}

// True when the host of an authority "USER@HOST:PORT" (each but HOST optional) is empty.
bool names_no_host(std::string authority) {
  authority.erase(0, authority.rfind('@') + 1);  // none: npos + 1 erases nothing
  return authority.empty() || authority.front() == ':';
}

}  // namespace

std::optional<std::string> routed_path(const std::string& target) {
  if (!has_http_scheme(target)) return httplib::detail::decode_url(raw_path(target, 0), false);
  const size_t authority = kHttpScheme.size();
  const size_t path = std::min(target.find_first_of("/?#", authority), target.size());
  if (names_no_host(target.substr(authority, path - authority))) return std::nullopt;
  const std::string raw = raw_path(target, path);
  return raw.empty() ? "/" : httplib::detail::decode_url(raw, false);
}

}  // namespace rayfarm
