// FarmService: `rayfarm broker --serve`, the head node that stays up. One
// Broker for the whole life of the service (workers register once and keep
// their loaded scene between jobs), the jobs of a state folder
// (service/job_service.h) and the HTTP API in front of them. Frames are
// rendered one after another by the same Broker::run as the one-shot
// `rayfarm broker`; around it the service journals every accepted row before
// it counts as done and restores journaled rows after a restart.
#pragma once

#include <atomic>
#include <memory>
#include <string>

#include "broker/broker.h"
#include "broker/broker_config.h"
#include "service/http_api.h"
#include "service/job_service.h"

namespace rayfarm {

struct ServeOptions {
  BrokerConfig broker;
  HttpOptions http;
  std::string state_dir;
  LogSink log;  // {} = stderr
  // Set (the stop signals' flag): a state folder locked by another broker is
  // waited for only until it is true, then LockWaitStopped (folder_lock.h).
  const std::atomic<bool>* stop = nullptr;
};

class FarmService {
 public:
  // Opens the state folder, binds the worker sockets and the HTTP API, and
  // writes their addresses to DIR/service.json. Throws InputError on failure.
  explicit FarmService(const ServeOptions& options);
  ~FarmService();

  // Serves until `stop` becomes true. A frame interrupted by `stop` keeps its
  // journaled rows for the next start.
  void run(const std::atomic<bool>& stop);

  // Logs why the service stops (e.g. "SIGTERM") and what the next start
  // resumes: a stop on a signal otherwise left no line in the journal.
  void log_stop(const std::string& cause);

  std::string http_address() const;
  const Broker& broker() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace rayfarm
