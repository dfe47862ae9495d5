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

// The position of the first "%2F" or "%2f" in `path` from `from`, npos for none.
size_t encoded_slash(const std::string& path, size_t from) {
  for (size_t at = path.find('%', from); at != std::string::npos; at = path.find('%', at + 1))
    if (path.compare(at + 1, 2, "2F") == 0 || path.compare(at + 1, 2, "2f") == 0) return at;
  return std::string::npos;
}

// Percent-decoded but for an encoded slash, which stays "%2F": it is a
// character of its segment (RFC 3986 2.2), not a separator. Decoded, a job id
// segment of "1%2Fcancel" cancelled job 1, and "/api/jobs%2F1" was job 1's status.
std::string decoded_path(const std::string& raw) {
  std::string path;
  size_t from = 0;
  for (size_t at = encoded_slash(raw, 0); at != std::string::npos; at = encoded_slash(raw, from)) {
    path += httplib::detail::decode_url(raw.substr(from, at - from), false) + "%2F";
    from = at + 3;
  }
  return path + httplib::detail::decode_url(raw.substr(from), false);
}

// True when the host of an authority "USER@HOST:PORT" (each but HOST optional) is empty.
bool names_no_host(std::string authority) {
  authority.erase(0, authority.rfind('@') + 1);  // none: npos + 1 erases nothing
  return authority.empty() || authority.front() == ':';
}

}  // namespace

std::optional<std::string> routed_path(const std::string& target) {
  if (!has_http_scheme(target)) return decoded_path(raw_path(target, 0));
  const size_t authority = kHttpScheme.size();
  const size_t path = std::min(target.find_first_of("/?#", authority), target.size());
  if (names_no_host(target.substr(authority, path - authority))) return std::nullopt;
  const std::string raw = raw_path(target, path);
  return raw.empty() ? "/" : decoded_path(raw);
}

}  // namespace rayfarm
