// Worker: a render server of the farm (`rayfarm worker`). A DEALER talks to the
// broker's ROUTER (register, fetch the job, receive tasks, return pixels,
// heartbeats) and a SUB hears its announcements; rendering runs on a separate
// thread (worker/render_engine.h). If the broker falls silent the worker
// reconnects with exponential back-off and registers again (Paranoid Pirate).
#pragma once

#include <atomic>
#include <functional>
#include <memory>
#include <string>

#include <zmq.hpp>

#include "worker/worker_config.h"

namespace rayfarm {

class Worker {
 public:
  // `context`: share one ZeroMQ context between many workers in one process
  // (tests, lab emulation); nullptr = own context.
  explicit Worker(WorkerConfig config, std::function<void(const std::string&)> log = {},
                  zmq::context_t* context = nullptr);
  ~Worker();
  Worker(const Worker&) = delete;
  Worker& operator=(const Worker&) = delete;

  // Serves until the broker says `shutdown` or `stop` becomes true (sends
  // `bye`); returns 0. Returns 1 when the broker speaks another protocol
  // version (no retry can help); a broker that is silent or unreachable is
  // retried. A job it cannot load or render is reported to the
  // broker (`job_failed`) and dropped; the worker stays up for the next one.
  int run(const std::atomic<bool>& stop);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Writes `line` on stderr as worker `name`'s log line, "rayfarm worker NAME:
// LINE", escaped as every log line is (tracer/log_text.h): it quotes what the
// broker sent, the endpoint a config gave, an error's text.
void write_worker_log(const std::string& name, const std::string& line);

}  // namespace rayfarm
