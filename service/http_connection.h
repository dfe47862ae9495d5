// HttpServer: cpp-httplib's server, each connection read through one buffered
// stream of its own (httplib 0.11's loop reads each request of a keep-alive
// connection through a new stream, and the bytes its buffer took past the
// request, a pipelined next request, were lost: that request was never
// answered). The stream also bounds what a request's head may cost a server
// thread: it must arrive whole within kRequestHeadSeconds (a client sending
// a byte every few seconds held a thread for ever, and 64 such clients every
// thread), and a line of it may not run past httplib's limits (it was kept
// in memory whatever its length), nor all of them past kMaxRequestHeadBytes. Between requests, and while a request's
// head is arriving, a connection holds no thread: one watcher thread polls
// all such connections and hands a connection to a server thread once its
// head is whole (each idle connection held one of the 64 threads for the
// keep-alive time, and a client that kept opening them kept every answer
// waiting). Its body then has a deadline too, pushed
// back only by the bytes it brings (a client sending a byte of it every 4 s,
// each read within httplib's 5 s, held a thread for ever), and a length:
// httplib keeps a chunked body whatever its size, past the payload limit it
// holds a body with a Content-Length to.
// The connections open at once are bounded, in all and from one client
// address: each holds a file and a buffer, and a client opening thousands of
// them ran the process out of files (jobs could not be written, a worker not
// connect). One past the bound is answered 503 at once and closed. So are
// the bodies being received, together: each may reach the payload limit, and
// many at once, each within it, took memory without bound.
#pragma once

#include <httplib.h>

#include <atomic>
#include <ctime>
#include <memory>
#include <string>

#include "broker/log_sink.h"

namespace rayfarm {

// The most a request's head may take, its lines together: each line is held
// to httplib's limit, but their number was not, and httplib keeps every
// header (42 MB of them sent in 3.5 s were all kept). Browsers' fit.
inline constexpr size_t kMaxRequestHeadBytes = 64 << 10;

// Time a request's head (request line and headers) has to arrive whole, from its first byte.
inline constexpr time_t kRequestHeadSeconds = 5;
// A body has as long again from the head's end, and a second more for every
// kMinBodyBytesPerSecond of it received: a client on a slow link can send
// the service's largest body, a trickle cannot hold a thread.
inline constexpr size_t kMinBodyBytesPerSecond = 64 << 10;

// Why httplib could not read the current request, which it answers 400 whatever the cause.
enum class RequestFault {
  none,
  line_too_long,  // a header line past CPPHTTPLIB_HEADER_MAX_LENGTH: 431
  head_too_long,  // its lines together past kMaxRequestHeadBytes: 431
  encoded_framing,  // a '%' in its Content-Length or Transfer-Encoding, which httplib decodes: 400
  folded_line,    // a header line begun with white space (obsolete line folding), which httplib drops: 400
  empty_idempotency_key,  // an Idempotency-Key header without a value, which httplib drops: 400
  head_too_slow,  // its head not whole within kRequestHeadSeconds: 408
  body_too_slow,  // its body slower than kMinBodyBytesPerSecond: 408
  body_too_long,  // its body past the payload limit, chunk framing counted: 413
  over_budget,    // its body past what the bodies being received may hold together: 503
};

class BodyBudget;  // the bytes of bodies being received, together

// Connections open at once, in all (a few files each for the rest of the
// process stay free under any usual open-file limit) and from one address
// (half of them: one client cannot shut out the others).
inline constexpr size_t kDefaultMaxConnections = 512;

class HttpServer : public httplib::Server {
 public:
  // `threads` serve requests whose head has arrived; waiting costs none.
  explicit HttpServer(size_t threads = 8);

  // Before listening: at most `total` connections open at once, at most
  // `per_client` of them from one address. `log` is told when refusals begin
  // (then at most once a minute while they go on), not of each.
  void set_connection_limits(size_t total, size_t per_client, LogSink log);
  // Before listening: the bytes the bodies of requests being received may
  // hold together (unbounded by default).
  void set_body_budget(size_t bytes);
  size_t body_budget() const;

  // For a handler before the body is read, on the thread serving the request:
  // sees that `bytes` of the budget in all are set aside for it (asked twice,
  // set aside once), until its answer is sent; false (nothing more set aside)
  // when the other requests' bodies leave too little.
  static bool reserve_body(size_t bytes);

  // For the error handler, on the thread that serves the request.
  static RequestFault request_fault();
  // For a handler, on the thread serving the request: its Host lines without
  // a value, which httplib drops (it keeps only headers with one).
  static size_t empty_host_lines();
  // Ends the connection once the response being written is sent: after an
  // error what follows the request may be its unread body, not a next request.
  static void close_after_response();

 private:
  class Waiting;      // the task queue: server threads, and the watcher of connections between requests
  struct Connection;  // one client's, passed between them
  class Admission;    // the count of open connections, in all and by address

  // Called by httplib's accept loop, on its thread: admits the connection (a
  // server thread then serves it) or refuses it 503, without waiting.
  bool process_and_close_socket(socket_t sock) override;
  void refuse(socket_t sock, const std::string& why);
  void serve(std::unique_ptr<Connection> connection);
  void finish(std::unique_ptr<Connection> connection);
  // Hands `connection` to the watcher; false (and kept) when there is none.
  bool park(std::unique_ptr<Connection>& connection);

  std::atomic<Waiting*> waiting_{nullptr};
  std::shared_ptr<Admission> admission_;
  std::shared_ptr<BodyBudget> body_budget_;
};

}  // namespace rayfarm
