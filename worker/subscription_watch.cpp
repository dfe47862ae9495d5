// The worker's watch on its announcement subscription; see subscription_watch.h.
#include "worker/subscription_watch.h"

#include <atomic>
#include <cstring>
#include <utility>

#include "protocol/transport.h"

namespace rayfarm {
namespace {

std::atomic<int> monitor_counter{0};

}  // namespace

// Only completed handshakes are watched: one event per connection, so the
// queue never fills and stopping the monitor never waits on it.
SubscriptionWatch::SubscriptionWatch(zmq::context_t& context, zmq::socket_t& sub, std::string endpoint,
                                     std::string origin)
    : sub_(sub), events_(context, zmq::socket_type::pair), endpoint_(std::move(endpoint)), origin_(std::move(origin)) {
  const std::string monitor = "inproc://rayfarm-subscription-" + std::to_string(monitor_counter++);
  if (zmq_socket_monitor(sub_.handle(), monitor.c_str(), ZMQ_EVENT_HANDSHAKE_SUCCEEDED) != 0) throw zmq::error_t();
  events_.set(zmq::sockopt::linger, 0);
  events_.connect(monitor);
}

SubscriptionWatch::~SubscriptionWatch() { zmq_socket_monitor(sub_.handle(), nullptr, 0); }

std::string SubscriptionWatch::serve_pending() {
  bool handshake = false;
  for (int i = 0; i < 1000; ++i) {
    const auto event = protocol::receive(events_);
    if (!event) break;
    uint16_t kind = 0;
    if (!event->empty() && (*event)[0].size() >= sizeof kind) std::memcpy(&kind, (*event)[0].data(), sizeof kind);
    handshake = handshake || kind == ZMQ_EVENT_HANDSHAKE_SUCCEEDED;
  }
  if (!handshake || reached_) return "";
  reached_ = true;
  return said_unreached_ ? "reached the broker's announcements at " + endpoint_ : "";
}

std::string SubscriptionWatch::overdue(std::chrono::milliseconds limit) {
  if (reached_ || said_unreached_ || std::chrono::steady_clock::now() - started_ < limit) return "";
  said_unreached_ = true;
  return "cannot subscribe to the broker's announcements at " + endpoint_ + " (" + origin_ +
         "): no connection there completed within " + std::to_string(limit.count()) +
         " ms (is the port firewalled, or not the broker's announce port?); retrying (meanwhile each job is fetched "
         "when the broker names it, later than an announcement would bring it)";
}

}  // namespace rayfarm
