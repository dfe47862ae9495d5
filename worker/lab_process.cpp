// Many workers in one process; see lab_process.h.
#include "worker/lab_process.h"

#include <sys/resource.h>

#include <cstdio>
#include <memory>
#include <thread>

#include "tracer/error.h"
#include "worker/worker.h"

namespace rayfarm {

void reserve_files_for_workers(size_t workers) {
  const rlim_t needed = static_cast<rlim_t>(workers * kFilesPerWorker + 64);  // + stdio, libraries, the context
  rlimit limit{};
  if (getrlimit(RLIMIT_NOFILE, &limit) != 0) return;
  if (limit.rlim_cur != RLIM_INFINITY && limit.rlim_cur >= needed) return;
  if (limit.rlim_max != RLIM_INFINITY && limit.rlim_max < needed)
    throw InputError("a lab of " + std::to_string(workers) + " machines needs about " + std::to_string(needed) +
                     " open files, but this process may open at most " + std::to_string(limit.rlim_max) +
                     " (RLIMIT_NOFILE hard limit; see `ulimit -Hn`): split the lab over several processes "
                     "or raise the limit");
  limit.rlim_cur = limit.rlim_max == RLIM_INFINITY ? needed : limit.rlim_max;
  if (setrlimit(RLIMIT_NOFILE, &limit) != 0)
    throw InputError("cannot raise RLIMIT_NOFILE to " + std::to_string(limit.rlim_cur) + " for a lab of " +
                     std::to_string(workers) + " machines");
}

int run_lab_process(const std::vector<WorkerConfig>& machines, const std::atomic<bool>& stop) {
  reserve_files_for_workers(machines.size());
  zmq::context_t context(2);
  context.set(zmq::ctxopt::max_sockets, static_cast<int>(machines.size() * kSocketSlotsPerWorker + 16));
  std::vector<std::unique_ptr<Worker>> workers;
  for (const WorkerConfig& cfg : machines) workers.push_back(std::make_unique<Worker>(cfg, nullptr, &context));
  std::fprintf(stderr, "rayfarm worker: lab of %zu machines\n", workers.size());
  std::atomic<int> failed{0};
  std::vector<std::thread> threads;
  for (size_t i = 0; i < workers.size(); ++i) {
    threads.emplace_back([&, i] {
      try {
        if (workers[i]->run(stop) != 0) ++failed;
      } catch (const std::exception& e) {  // one machine's failure must not abort the others
        std::fprintf(stderr, "rayfarm worker %s: stopped: %s\n", machines[i].name.c_str(), e.what());
        ++failed;
      }
    });
  }
  for (auto& t : threads) t.join();
  return failed > 0 ? 1 : 0;
}

}  // namespace rayfarm
