// Moving RFP/3 frames over ZeroMQ: multipart send/receive with the ROUTER
// identity kept apart from the message frames, and socket options every farm
// socket shares (no linger, a per-frame size cap so a peer cannot make us
// allocate more than the protocol allows).
#pragma once

#include <optional>
#include <string>

#include <zmq.hpp>

#include "protocol/codec.h"

namespace rayfarm::protocol {

// Applies linger 0 and ZMQ_MAXMSGSIZE to a freshly created socket: ZeroMQ
// drops the connection of a peer that announces a larger frame before it has
// arrived, so nobody can make us buffer more than the protocol allows.
void configure_socket(zmq::socket_t& socket, uint64_t max_frame_bytes);

// The largest frame a broker sends: a `job` with the largest scene.
inline constexpr uint64_t kMaxBrokerFrameBytes = kMaxSceneBytes;

// Receives one multipart message without blocking; nullopt when none is queued.
// With `identity`, the first frame is the ROUTER peer identity. With `user_id`,
// the connection's ZAP "User-Id" ("" if none; the broker's ZAP handler sets it
// to the peer's CURVE public key).
std::optional<Frames> receive(zmq::socket_t& socket, std::string* identity = nullptr,
                              std::string* user_id = nullptr);

// Sends `frames` (prefixed by `identity` for a ROUTER). Never blocks: returns
// false if the message could not be queued (peer gone or its queue full).
bool send(zmq::socket_t& socket, const Frames& frames, const std::string* identity = nullptr);
bool send(zmq::socket_t& socket, const Message& message, const std::string* identity = nullptr);

// Sends `frames`, waiting while the peer's queue is full (up to the socket's
// ZMQ_SNDTIMEO). For inproc hand-offs that must not drop a message.
bool send_waiting(zmq::socket_t& socket, const Frames& frames);

// zmq::poll that treats a signal (EINTR) as "nothing happened", so SIGTERM
// handlers get to set their flag instead of killing the loop with an exception.
void poll_interruptible(zmq::pollitem_t* items, size_t count, int timeout_ms);

// Why ZeroMQ would not use the port of a tcp:// endpoint as written, or ""
// when it would (other transports are left to ZeroMQ). ZeroMQ reads the port
// with atoi into 16 bits: "tcp://*:99999" binds port 34463, "-5" is 65531 and
// "5555x" is 5555, each without an error.
std::string tcp_port_problem(const std::string& endpoint);

// Why a farm's socket (a broker's bind, a worker's connect) cannot use
// `endpoint`'s transport, or "" for tcp://. Other transports were taken and
// failed later: a broker bound to ipc:// for its announcements stopped at the
// first registration (the welcome names a port), and refused ipc:// workers
// as not loopback; inproc:// reaches no other process.
std::string farm_transport_problem(const std::string& endpoint);

// Why no broker can be at `endpoint`, for a worker to connect to, or "":
// farm_transport_problem's, tcp_port_problem's, or a tcp:// port 0 or * (a
// bind's "any free port": a broker bound so listens on the port it took, not
// on 0). ZeroMQ connects to such an endpoint and retries forever, and the
// worker said only "no broker answered".
std::string broker_endpoint_problem(const std::string& endpoint);

// Why the host of a tcp:// endpoint to connect to cannot be used, or "" when
// it can: an IP address, "*", or a name getaddrinfo resolves. ZeroMQ keeps
// retrying an unresolvable name in silence, which a worker reported as "no
// broker answered". Other transports are left to ZeroMQ.
std::string tcp_host_problem(const std::string& endpoint);

// The port of a bound tcp endpoint such as "tcp://127.0.0.1:40123".
int endpoint_port(const std::string& endpoint);

// "tcp://host:port" -> "tcp://host:<port>" (for the SUB socket next to a DEALER).
std::string endpoint_with_port(const std::string& endpoint, int port);

}  // namespace rayfarm::protocol
