// HandshakeFailures: the broker's watch on its worker socket's connections.
#include <doctest/doctest.h>

#include <fcntl.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <future>
#include <memory>
#include <thread>
#include <zmq.hpp>

#include "broker/handshake_failures.h"
#include "protocol/transport.h"

using namespace rayfarm;

namespace {

// Opens a connection to 127.0.0.1:port and closes it at once, not waiting
// for the listener to accept it.
void touch(int port) {
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_NONBLOCK, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<uint16_t>(port));
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ::connect(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr);
  ::close(fd);
}

}  // namespace

TEST_CASE("handshake failures: a watch whose events were left unread still ends, not deadlocking on the full queue") {
  // Out of files, the listener fails each accept again and again, an event
  // each; a broker that stopped reading them (ending its job) hung for good
  // in this destructor, as ZeroMQ's I/O thread held the monitor's lock while
  // waiting for room in the full queue. Connections opened and closed unread
  // fill the queue the same way (accepted, disconnected).
  zmq::context_t ctx;
  zmq::socket_t router(ctx, zmq::socket_type::router);
  router.set(zmq::sockopt::linger, 0);
  auto watch = std::make_unique<HandshakeFailures>(ctx, router, "", nullptr);
  router.bind("tcp://127.0.0.1:*");
  const int port = protocol::endpoint_port(router.get(zmq::sockopt::last_endpoint));
  for (int i = 0; i < 4000; ++i) touch(port);
  std::this_thread::sleep_for(std::chrono::milliseconds(500));  // the I/O thread meets the full queue
  auto ended = std::async(std::launch::async, [&] { watch.reset(); });
  const bool in_time = ended.wait_for(std::chrono::seconds(20)) == std::future_status::ready;
  CHECK(in_time);
  if (!in_time) std::_Exit(1);  // deadlocked: the process could never end by itself
}
