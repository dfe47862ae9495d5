// The routes and their methods; see route_table.h.
#include "status/route_table.h"

#include <httplib.h>

#include <algorithm>

#include <nlohmann/json.hpp>

namespace rayfarm {

void RouteTable::get(const std::string& pattern, Handler handler) {
  server_.Get(pattern, std::move(handler));
  routes_.push_back({std::regex(pattern), {"GET", "HEAD"}});
}

void RouteTable::post(const std::string& pattern, Handler handler) {
  server_.Post(pattern, std::move(handler));
  routes_.push_back({std::regex(pattern), {"POST"}});
}

std::vector<std::string> RouteTable::methods_of(const std::string& path) const {
  std::vector<std::string> methods;
  for (const Route& r : routes_)
    if (std::regex_match(path, r.pattern)) methods.insert(methods.end(), r.methods.begin(), r.methods.end());
  return in_order(std::move(methods));
}

std::vector<std::string> RouteTable::in_order(std::vector<std::string> methods) {
  if (methods.empty()) return methods;
  // One order whichever route was mounted first: GET, HEAD, POST (alphabetical).
  std::sort(methods.begin(), methods.end());
  methods.erase(std::unique(methods.begin(), methods.end()), methods.end());
  methods.push_back("OPTIONS");
  return methods;
}

std::string RouteTable::allowed_methods(const std::string& path) const {
  std::vector<std::string> methods = methods_of(path);
  if (methods.empty()) {
    for (const Route& r : routes_) methods.insert(methods.end(), r.methods.begin(), r.methods.end());
    methods = in_order(std::move(methods));
  }
  std::string allow;
  for (const std::string& m : methods) allow += (allow.empty() ? "" : ", ") + m;
  return allow;
}

bool RouteTable::answer_other_method(const httplib::Request& req, httplib::Response& res) const {
  const std::vector<std::string> methods = methods_of(req.path);
  const bool routed = std::find(methods.begin(), methods.end(), req.method) != methods.end();
  if (methods.empty() || (routed && req.method != "OPTIONS")) return false;
  const std::string allow = allowed_methods(req.path);  // methods is not empty: the path's own
  res.set_header("Allow", allow);
  if (req.method == "OPTIONS") {
    res.status = 204;
  } else {
    res.status = 405;
    const std::string reason = req.method + " " + req.path + ": method not allowed (allowed: " + allow + ")";
    res.set_content(nlohmann::json{{"error", reason}}.dump(2) + "\n", "application/json");
  }
  return true;
}

}  // namespace rayfarm
