// Whether the worker's subscription to the broker's announcements ever
// reached the broker. ZeroMQ dials a refused, firewalled or wrong announce
// port again and again without a word, and the worker still renders: it
// fetches each job the broker names on its worker socket. So nothing said
// that the announcements never came: every job loaded a heartbeat late, none
// early while the one before it renders. This watches the SUB socket's
// handshakes; the worker says once when none has completed within the
// broker's liveness period, and once more when one completes after that.
#pragma once

#include <chrono>
#include <string>

#include <zmq.hpp>

namespace rayfarm {

class SubscriptionWatch {
 public:
  // Starts watching `sub`, which is about to dial `endpoint`; `origin` says
  // where the endpoint came from ("--subscribe").
  SubscriptionWatch(zmq::context_t& context, zmq::socket_t& sub, std::string endpoint, std::string origin);
  ~SubscriptionWatch();  // before `sub` closes
  SubscriptionWatch(const SubscriptionWatch&) = delete;
  SubscriptionWatch& operator=(const SubscriptionWatch&) = delete;

  zmq::socket_t& socket() { return events_; }  // poll it for ZMQ_POLLIN

  // Reads the events queued now, never blocking: the line to log when the
  // subscription was said unreached and a handshake has completed since, else "".
  std::string serve_pending();
  // The line to log once `limit` has passed since the watch began without a
  // completed handshake, the first time only; else "".
  std::string overdue(std::chrono::milliseconds limit);

 private:
  zmq::socket_t& sub_;
  zmq::socket_t events_;
  std::string endpoint_, origin_;
  std::chrono::steady_clock::time_point started_ = std::chrono::steady_clock::now();
  bool reached_ = false;
  bool said_unreached_ = false;
};

}  // namespace rayfarm
