// RouteTable: the service's HTTP routes with the methods each serves, mounted
// on a cpp-httplib server through it. httplib answers a known path asked with
// another method 404, as if the path did not exist, and OPTIONS 404 anywhere;
// with the table the server answers 405 with an Allow header naming the
// path's methods, and OPTIONS 204 with that header (RFC 9110 15.5.6, 9.3.7).
#pragma once

#include <functional>
#include <regex>
#include <string>
#include <vector>

namespace httplib {
class Server;
struct Request;
struct Response;
}  // namespace httplib

namespace rayfarm {

// A number in a route's path (a job id, a frame number), one spelling per
// number: decimal digits without leading zeros, at most 19 (within 64 bits).
// "/api/jobs/01" or "/api/jobs/+1" is no path of the API.
inline constexpr const char* kPathNumber = "(0|[1-9][0-9]{0,18})";

class RouteTable {
 public:
  using Handler = std::function<void(const httplib::Request&, httplib::Response&)>;

  explicit RouteTable(httplib::Server& server) : server_(server) {}

  // `pattern`: a regular expression the whole path matches, as httplib's.
  void get(const std::string& pattern, Handler handler);  // HEAD too (httplib answers it from GET)
  void post(const std::string& pattern, Handler handler);

  // For the server's pre-routing handler: answers OPTIONS of a known path and
  // a method its routes do not serve, and returns true; false for the rest
  // (served by its routes, or an unknown path: httplib's 404).
  bool answer_other_method(const httplib::Request& req, httplib::Response& res) const;

  // The methods of the routes `path` matches, e.g. "GET, HEAD, OPTIONS"; for
  // a path no route matches, those of every route.
  std::string allowed_methods(const std::string& path) const;

 private:
  // Every method the routes matching `path` serve, then OPTIONS; empty for none.
  std::vector<std::string> methods_of(const std::string& path) const;
  // Sorted, each once, then OPTIONS; empty for none.
  static std::vector<std::string> in_order(std::vector<std::string> methods);

  struct Route {
    std::regex pattern;
    std::vector<std::string> methods;
  };
  httplib::Server& server_;
  std::vector<Route> routes_;
};

}  // namespace rayfarm
