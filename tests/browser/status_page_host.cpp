// The status page's own server for the browser test: a local farm (this
// process's broker and one throttled `rayfarm worker` process) renders one
// scene while a StatusServer serves the page and its API over a StatusBoard.
// Prints "serving URL" when the page is up and "job done" when the job is; then
// keeps serving until SIGTERM, so the test can stop the broker under the page.
#include <csignal>
#include <cstdio>
#include <string>
#include <thread>

#include "broker/local_farm.h"
#include "status/status_board.h"
#include "status/status_routes.h"
#include "tracer/image_io.h"
#include "tracer/text_file.h"

using namespace rayfarm;

namespace {

volatile std::sig_atomic_t g_stop = 0;
void on_signal(int) { g_stop = 1; }

}  // namespace

// status_page_host RAYFARM SCENE OUT.png WIDTH HEIGHT SPP THROTTLE
int main(int argc, char** argv) {
  if (argc != 8) {
    std::fprintf(stderr, "usage: %s RAYFARM SCENE OUT.png WIDTH HEIGHT SPP THROTTLE\n", argv[0]);
    return 2;
  }
  std::signal(SIGTERM, on_signal);
  std::signal(SIGINT, on_signal);
  StatusBoard board;
  StatusServer server("127.0.0.1", 0);
  mount_status_page(server.server());
  mount_status_api(server.server(), board, [&board] { return board.jobs_by_state(); });
  mount_board_jobs(server.server(), board);
  server.start();
  std::printf("serving %s\n", server.address().c_str());
  std::fflush(stdout);

  RenderSettings settings;
  settings.width = std::stoi(argv[4]);
  settings.height = std::stoi(argv[5]);
  settings.spp = std::stoi(argv[6]);
  LocalFarmOptions o;
  o.machines = {LocalWorker{"slow-1", 21.0, std::stod(argv[7])}};
  o.threads = 1;
  o.credit = 1;
  o.base_task_rows = 1;
  o.executable = argv[1];
  o.progress = false;
  o.watch = [&board](const FarmProgress& p) {
    board.update(p);
    if (g_stop) throw std::runtime_error("stopped");
  };
  const LocalFarmResult r = render_local_farm(read_text_file(argv[2]), argv[2], settings, o);
  board.set_record(r.record["job"].get<uint64_t>(), r.record);
  write_image(argv[3], r.width, r.height, r.rgb);
  std::printf("job done\n");
  std::fflush(stdout);
  while (!g_stop) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  return 0;
}
