// HttpServer: cpp-httplib's server, each connection read through one buffered
// stream of its own (httplib 0.11's loop reads each request of a keep-alive
// connection through a new stream, and the bytes its buffer took past the
// request, a pipelined next request, were lost: that request was never
// answered).
#pragma once

#include <httplib.h>

namespace rayfarm {

class HttpServer : public httplib::Server {
 public:
  // For the error handler, on the thread that serves the request: ends the connection once the response being written is sent: after an
  // error what follows the request may be its unread body, not a next request.
  static void close_after_response();

 private:
  bool process_and_close_socket(socket_t sock) override;
};

}  // namespace rayfarm
