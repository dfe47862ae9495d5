// One process running many workers (`rayfarm worker --lab`): every machine of
// a lab as a Worker thread sharing one ZeroMQ context. Each worker holds a few
// sockets and file descriptors, so a big lab meets two limits that a single
// worker never does: the context's ZMQ_MAX_SOCKETS (1023 by default) and the
// process's RLIMIT_NOFILE. Both are raised before any socket exists, and a lab
// that still does not fit fails at once with a message naming the limit,
// instead of aborting midway with "Too many open files".
#pragma once

#include <atomic>
#include <cstddef>
#include <vector>

#include "worker/worker_config.h"

namespace rayfarm {

// What one Worker costs: a DEALER, a SUB, the two ends of its render thread's
// doorbell, of its handshake monitor and of its subscription's monitor; each
// socket has an eventfd, each TCP connection a socket. A worker that
// reconnects opens a new DEALER, SUB and monitors before libzmq's reaper
// thread has freed the old ones, so a context holds room for twice that: on a
// loaded machine hundreds of lab workers reconnect at once (2,000 workers on 2
// cores ran out of sockets without it).
inline constexpr size_t kSocketsPerWorker = 8;
inline constexpr size_t kSocketSlotsPerWorker = 2 * kSocketsPerWorker;
inline constexpr size_t kFilesPerWorker = 20;  // 2 x 8 eventfds + 2 TCP + margin

// Raises the soft RLIMIT_NOFILE to the hard limit if `workers` need it;
// throws InputError naming the limit when even the hard limit is too low.
void reserve_files_for_workers(size_t workers);

// Runs every config as a worker thread until `stop` or the broker's shutdown.
// Returns 0 if every worker ended cleanly, 1 if any failed (each is logged).
int run_lab_process(const std::vector<WorkerConfig>& machines, const std::atomic<bool>& stop);

}  // namespace rayfarm
