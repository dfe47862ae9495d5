// Who may talk to a broker, and how much: real brokers on 127.0.0.1 ephemeral
// ports and hand-driven peers. A frame larger than the largest legitimate one
// is dropped by ZeroMQ before it arrives (ZMQ_MAXMSGSIZE).
#include <doctest/doctest.h>

#include <mutex>
#include <string>
#include <vector>

#include "broker/broker.h"
#include "protocol/transport.h"

using namespace rayfarm;

namespace {

struct Log {
  std::mutex mutex;
  std::vector<std::string> lines;
  LogSink sink() {
    return [this](const std::string& line) {
      std::lock_guard<std::mutex> lock(mutex);
      lines.push_back(line);
    };
  }
  int count(const std::string& part) {
    std::lock_guard<std::mutex> lock(mutex);
    int n = 0;
    for (const std::string& l : lines) n += l.find(part) != std::string::npos;
    return n;
  }
};

BrokerConfig loopback_config() {
  BrokerConfig cfg;
  cfg.bind = cfg.announce_bind = "tcp://127.0.0.1:*";
  cfg.progress = false;
  cfg.min_workers = 0;
  return cfg;
}

}  // namespace

TEST_CASE("admission: the ROUTER's frame cap follows the largest legitimate result") {
  BrokerConfig cfg = loopback_config();
  cfg.max_image_width = 640;
  cfg.max_task_rows = 256;
  CHECK(max_worker_frame_bytes(cfg) == 40 + 640 * 256 * 12);
  cfg.max_task_rows = 1;
  CHECK(max_worker_frame_bytes(cfg) == protocol::kMaxJsonBytes);  // a JSON frame may be larger
  cfg.max_task_rows = 1000;
  CHECK(task_rows_for(cfg, 1e6) == 1000);  // no task is cut taller than the cap allows
}

TEST_CASE("admission: an oversized frame never reaches the broker") {
  Log log;
  BrokerConfig cfg = loopback_config();
  cfg.max_image_width = 64;
  cfg.max_task_rows = 4;  // largest result 3,112 bytes: the 1 MiB JSON limit rules
  Broker broker(cfg, log.sink());
  zmq::context_t ctx(1);
  zmq::socket_t big(ctx, zmq::socket_type::dealer), small(ctx, zmq::socket_type::dealer);
  for (zmq::socket_t* s : {&big, &small}) {
    protocol::configure_socket(*s, protocol::kMaxBrokerFrameBytes);
    s->connect(broker.endpoint());
  }
  // 16 MiB from one peer: before the cap it arrived whole (and was rejected only then).
  REQUIRE(protocol::send(big, protocol::Frames{std::string(16u << 20, '{')}));
  REQUIRE(protocol::send(small, protocol::Frames{"{not json"}));
  broker.serve_for(1.0);
  CHECK(log.count("rejected message from unknown peer") == 1);  // the small one only
  CHECK(log.count("not valid JSON") == 1);
}
