// The broker's log of handshakes that fail inside ZeroMQ; see handshake_failures.h.
#include "broker/handshake_failures.h"

#include <sys/resource.h>

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <thread>

#include "protocol/transport.h"

namespace rayfarm {
namespace {

std::atomic<int> monitor_counter{0};

}  // namespace

HandshakeFailures::HandshakeFailures(zmq::context_t& context, zmq::socket_t& watched, std::string broker_public_key,
                                     std::function<void(const std::string&)> log)
    : watched_(watched), events_(context, zmq::socket_type::pair), broker_public_key_(std::move(broker_public_key)),
      log_(std::move(log)) {
  const std::string endpoint = "inproc://rayfarm-broker-handshakes-" + std::to_string(monitor_counter++);
  if (zmq_socket_monitor(watched_.handle(), endpoint.c_str(),
                         ZMQ_EVENT_HANDSHAKE_FAILED_PROTOCOL | ZMQ_EVENT_ACCEPTED | ZMQ_EVENT_ACCEPT_FAILED |
                             ZMQ_EVENT_DISCONNECTED) != 0)
    throw zmq::error_t();
  events_.set(zmq::sockopt::linger, 0);
  events_.connect(endpoint);
}

// Stopping the monitor takes the lock under which ZeroMQ's I/O thread sends
// each event, and that send waits while the event queue is full: a storm of
// events the broker no longer read (out of files, the listener fails each
// accept again and again) held the lock for good, and a broker ending its job
// hung in this destructor. So the monitor is stopped on a thread of its own
// while this one empties the queue.
HandshakeFailures::~HandshakeFailures() {
  std::atomic<bool> stopped{false};
  std::thread stopper([&] {
    zmq_socket_monitor(watched_.handle(), nullptr, 0);
    stopped = true;
  });
  zmq::pollitem_t item{events_.handle(), 0, ZMQ_POLLIN, 0};
  try {
    while (!stopped) {
      protocol::poll_interruptible(&item, 1, 1);
      while (protocol::receive(events_)) {
      }
    }
  } catch (const zmq::error_t&) {  // the context ending: nothing left to send events to
  }
  stopper.join();
}

std::string HandshakeFailures::explain(uint32_t zmtp_error, const std::string& endpoint) const {
  const std::string where = "a handshake on " + endpoint + " failed: ";
  switch (zmtp_error) {
    case ZMQ_PROTOCOL_ERROR_ZMTP_CRYPTOGRAPHIC:
      return where + "the peer does not hold this broker's public key " + broker_public_key_ +
             " (a worker's --broker-key must be this broker's .pub)";
    case ZMQ_PROTOCOL_ERROR_ZMTP_MECHANISM_MISMATCH:
      return where + (broker_public_key_.empty()
                          ? "the peer uses CURVE keys and this broker does not (give the broker --key and --allow, "
                            "or the worker neither --key nor --broker-key)"
                          : "the peer has no CURVE keys and this farm admits invited keys only (give the worker "
                            "--key and --broker-key)");
    default: {
      char code[16];
      std::snprintf(code, sizeof code, "0x%08x", zmtp_error);
      return where + "ZeroMQ protocol error " + code + " (is the peer a rayfarm worker of this version?)";
    }
  }
}

void HandshakeFailures::serve_pending() {
  for (int i = 0; i < 1000; ++i) {
    auto event = protocol::receive(events_);
    if (!event) return;
    // A monitor event: frame 1 is the event (u16) and its value (u32), frame 2 the endpoint.
    if (event->size() != 2 || (*event)[0].size() != 6) continue;
    uint16_t id = 0;
    uint32_t zmtp_error = 0;
    std::memcpy(&id, (*event)[0].data(), 2);
    std::memcpy(&zmtp_error, (*event)[0].data() + 2, 4);
    if (id == ZMQ_EVENT_ACCEPTED) ++accepted_;
    if (id == ZMQ_EVENT_DISCONNECTED) ++disconnected_;
    if (id != ZMQ_EVENT_HANDSHAKE_FAILED_PROTOCOL && id != ZMQ_EVENT_ACCEPT_FAILED) continue;
    // A failing peer reconnects every few hundred ms: one line a minute per kind of failure.
    const auto now = std::chrono::steady_clock::now();
    auto& last = id == ZMQ_EVENT_ACCEPT_FAILED ? last_accept_failure_ : last_logged_[zmtp_error];
    if (last.time_since_epoch().count() != 0 && now - last < std::chrono::minutes(1)) continue;
    last = now;
    if (log_) log_(id == ZMQ_EVENT_ACCEPT_FAILED ? explain_accept(zmtp_error, (*event)[1]) : explain(zmtp_error, (*event)[1]));
  }
}

// The value of an accept failure is its errno. Out of files, the workers that
// connect past the limit are turned away in the handshake, where they can only
// guess at keys and ports, and the broker itself may fail to write its image.
std::string HandshakeFailures::explain_accept(uint32_t error, const std::string& endpoint) {
  std::string line = "cannot accept a connection on " + endpoint + ": " + std::strerror(static_cast<int>(error));
  if (error != EMFILE && error != ENFILE) return line;
  rlimit limit{};
  const std::string files =
      getrlimit(RLIMIT_NOFILE, &limit) == 0 && limit.rlim_cur != RLIM_INFINITY
          ? std::to_string(limit.rlim_cur) + " (RLIMIT_NOFILE; each worker holds two connections)"
          : "(RLIMIT_NOFILE)";
  return line + "; this broker may open " + files + ": workers beyond that never register, and the image, record "
         "or journal may not be written; raise the limit (`ulimit -n`, LimitNOFILE= of a systemd service)";
}

}  // namespace rayfarm
