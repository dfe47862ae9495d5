// HttpServer: cpp-httplib's server, each connection read through one buffered
// stream of its own (httplib 0.11's loop reads each request of a keep-alive
// connection through a new stream, and the bytes its buffer took past the
// request, a pipelined next request, were lost: that request was never
// answered). A line of a request's head may not run past httplib's limits
// (it was kept in memory whatever its length).
#pragma once

#include <httplib.h>

namespace rayfarm {

// Why httplib could not read the current request's head, which it answers 400 whatever the cause.
enum class HeadFault {
  none,
  line_too_long,  // a header line past CPPHTTPLIB_HEADER_MAX_LENGTH: 431
};

class HttpServer : public httplib::Server {
 public:
  // For the error handler, on the thread that serves the request.
  static HeadFault head_fault();
  // Ends the connection once the response being written is sent: after an
  // error what follows the request may be its unread body, not a next request.
  static void close_after_response();

 private:
  bool process_and_close_socket(socket_t sock) override;
};

}  // namespace rayfarm
