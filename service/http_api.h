// HttpApi: the service's HTTP front door (docs/api.md), cpp-httplib on its own
// threads over a JobService. It only translates: JSON in, JSON out, errors as
// {"error": "reason"} with 400 (bad input), 401 (token), 404 (no such job or
// frame), 405 (a method the path does not serve), 408 (a head too slow), 409
// (not finished / already finished), 411 (a POST without a length), 422 (an
// Idempotency-Key already used for another body), 431 (a
// header line too long), 501 (a method or transfer coding not known) or 503
// (too many connections open, or request bodies being received; see
// http_connection.h); an
// error answer closes its connection. Loopback by default; bound
// to any other address it requires a bearer token and refuses to start without.
#pragma once

#include <memory>
#include <string>

#include "broker/log_sink.h"
#include "service/http_connection.h"
#include "service/job_service.h"
#include "status/status_board.h"

namespace rayfarm {

struct HttpOptions {
  std::string host = "127.0.0.1";
  int port = 8080;    // 0 = any free port (read it back with address())
  std::string token;  // "" = no authentication (loopback only)
  // Connections open at once (--http-connections); one address may hold half.
  size_t max_connections = kDefaultMaxConnections;
  // Bytes the bodies being received may hold together (a job is at most 512
  // MiB): past it a request is answered 503, to retry once others are in.
  size_t body_budget = size_t(1) << 30;
};

// Parses "HOST:PORT" (InputError "--http: expected HOST:PORT").
HttpOptions parse_http_address(const std::string& text);
// True for 127.0.0.0/8, ::1 and "localhost".
bool is_loopback(const std::string& host);
// The token in `path`, surrounding white space removed; InputError if empty,
// or if a line break or control character is left inside it.
std::string read_token_file(const std::string& path);

// What keeps `key` from being an Idempotency-Key (docs/api.md), "" if
// nothing: "expected 1 to 255 printable ASCII characters, found ...".
std::string idempotency_key_fault(const std::string& key);

class HttpApi {
 public:
  // Binds and starts serving. InputError if the address cannot be bound or is
  // not loopback and no token is set.
  // With a `status` board it also serves the status page and its live API
  // (status/status_routes.h); the page's own files need no token.
  // `log` is told when connections are refused for the limits, and what a
  // request that failed inside the service (500) threw ({} = stderr).
  HttpApi(JobService& jobs, const HttpOptions& options, const StatusBoard* status = nullptr, LogSink log = {});
  ~HttpApi();  // stops serving and joins its threads
  HttpApi(const HttpApi&) = delete;
  HttpApi& operator=(const HttpApi&) = delete;

  // e.g. "http://127.0.0.1:41234"
  std::string address() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace rayfarm
