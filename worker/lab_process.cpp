// Many workers in one process; see lab_process.h.
#include "worker/lab_process.h"

#include <cstdio>
#include <memory>
#include <string>
#include <thread>

#include "broker/open_files.h"
#include "tracer/error.h"
#include "worker/worker.h"

namespace rayfarm {

void reserve_files_for_workers(size_t workers) {
  reserve_open_files(workers * kFilesPerWorker + 64,  // + stdio, libraries, the context
                     "a lab of " + std::to_string(workers) + " machines",
                     "split the lab over several processes or raise the limit");
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
        write_worker_log(machines[i].name, std::string("stopped: ") + e.what());  // it may quote the config
        ++failed;
      }
    });
  }
  for (auto& t : threads) t.join();
  return failed > 0 ? 1 : 0;
}

}  // namespace rayfarm
