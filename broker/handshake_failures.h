// Handshakes that fail before admission is asked. The ZAP handler
// (broker/admission.h) judges a peer only once its CURVE handshake has
// succeeded: a worker holding another broker's public key, or a peer whose
// keys do not match the broker's (keys on one side only), fails earlier,
// inside ZeroMQ, and neither the ZAP handler nor the protocol ever sees it.
// This watches the socket's handshake events so the broker says why such a
// worker never registers, at most once a minute per kind of failure. It also
// counts the connections accepted: a peer that connects and never registers
// failed where neither side may have said why (see accepted()), and says when
// a connection cannot even be accepted (the broker is out of files).
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <string>

#include <zmq.hpp>

namespace rayfarm {

class HandshakeFailures {
 public:
  // Starts watching `watched` (call before it binds). `broker_public_key` is
  // "" for a broker without keys.
  HandshakeFailures(zmq::context_t& context, zmq::socket_t& watched, std::string broker_public_key,
                    std::function<void(const std::string&)> log);
  ~HandshakeFailures();

  zmq::socket_t& socket() { return events_; }  // poll it for ZMQ_POLLIN

  // Logs every failure queued now; never blocks.
  void serve_pending();

  // TCP connections accepted so far (counted by serve_pending).
  int accepted() const { return accepted_; }
  // Of those, the ones not closed since: a lost worker that was paused (say
  // SIGSTOP) keeps its connection open, and speaks on it again when resumed.
  int open_connections() const { return accepted_ > disconnected_ ? accepted_ - disconnected_ : 0; }

 private:
  std::string explain(uint32_t zmtp_error, const std::string& endpoint) const;
  static std::string explain_accept(uint32_t error, const std::string& endpoint);

  zmq::socket_t& watched_;
  zmq::socket_t events_;
  std::string broker_public_key_;
  std::function<void(const std::string&)> log_;
  std::map<uint32_t, std::chrono::steady_clock::time_point> last_logged_;
  std::chrono::steady_clock::time_point last_accept_failure_{};
  int accepted_ = 0;
  int disconnected_ = 0;
};

}  // namespace rayfarm
