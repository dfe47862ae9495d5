// The status page's HTTP routes (status/status_routes.h) on a real cpp-httplib
// server over a StatusBoard fed by a real local farm (worker processes,
// ZeroMQ): the page, the worker table, the preview equal to the final image,
// /metrics. The service's own mounting is tested in farm_service_test.cpp.
#include <doctest/doctest.h>

#include <httplib.h>

#include <string>
#include <thread>

#include "broker/local_farm.h"
#include "status/page_files.h"
#include "status/preview.h"
#include "status/route_table.h"
#include "status/status_board.h"
#include "status/status_routes.h"
#include "tests/test_paths.h"
#include "tracer/text_file.h"

using namespace rayfarm;

namespace {

// A server on 127.0.0.1, any free port, on its own thread.
struct TestServer {
  httplib::Server server;
  RouteTable routes{server};
  int port = 0;
  std::thread thread;
  void start() {
    port = server.bind_to_any_port("127.0.0.1");
    REQUIRE(port > 0);
    thread = std::thread([this] { server.listen_after_bind(); });
  }
  ~TestServer() {
    server.stop();
    if (thread.joinable()) thread.join();
  }
};

}  // namespace

TEST_CASE("status routes: the embedded page is served at / with its files") {
  REQUIRE(page_files().size() == 3);
  CHECK(page_files()[0].name == "index.html");
  CHECK(find_page_file("/") == &page_files()[0]);
  CHECK(find_page_file("/status.js") != nullptr);
  CHECK(find_page_file("/../CMakeLists.txt") == nullptr);
  CHECK(find_page_file("/api/jobs") == nullptr);
  CHECK(page_bytes() == read_text_file(test::source_dir() + "/status/web/index.html").size() +
                            read_text_file(test::source_dir() + "/status/web/status.css").size() +
                            read_text_file(test::source_dir() + "/status/web/status.js").size());
  MESSAGE("status page: " << page_bytes() << " bytes");

  TestServer s;
  mount_status_page(s.routes);
  s.start();
  httplib::Client client("127.0.0.1", s.port);
  const auto page = client.Get("/");
  REQUIRE(page);
  CHECK(page->status == 200);
  CHECK(page->get_header_value("Content-Type") == "text/html; charset=utf-8");
  CHECK(page->body == std::string(page_files()[0].body));
  // The page loads nothing from elsewhere: no absolute URLs in any file.
  for (const PageFile& f : page_files()) {
    CAPTURE(f.name);
    CHECK(f.body.find("src=\"http") == std::string_view::npos);
    CHECK(f.body.find("href=\"http") == std::string_view::npos);
    CHECK(f.body.find("url(http") == std::string_view::npos);
    CHECK(f.body.find("@import") == std::string_view::npos);
  }
  const auto js = client.Get("/status.js");
  REQUIRE(js);
  CHECK(js->get_header_value("Content-Type") == "text/javascript; charset=utf-8");
  CHECK(client.Get("/nothing.js")->status == 404);
}

TEST_CASE("status routes: a local farm job through the API: workers, preview, metrics") {
  StatusBoard board;
  TestServer s;
  mount_status_api(s.routes, board,
                   StatusSources{[] { return std::map<std::string, int>{{"done", 1}, {"queued", 0}}; },
                                 [](uint64_t job) { return job == 42 ? std::optional<std::string>("png") : std::nullopt; }});
  s.start();

  RenderSettings settings;
  settings.width = 40;
  settings.height = 30;
  settings.spp = 1;
  settings.threads = 1;
  LocalFarmOptions o;
  o.workers = 2;
  o.threads = 1;
  o.base_task_rows = 2;
  o.executable = test::rayfarm_exe();
  o.progress = false;
  o.deadline_s = 60;
  o.watch = [&board](const FarmProgress& p) { board.update(p, 7); };
  const std::string scene = read_text_file(test::source_dir() + "/scenes/balls.nff");
  const LocalFarmResult r = render_local_farm(scene, "balls.nff", settings, o);

  httplib::Client client("127.0.0.1", s.port);
  const nlohmann::json workers = nlohmann::json::parse(client.Get("/api/workers")->body);
  REQUIRE(workers.size() == 2);
  CHECK(workers[0]["rows_done"].get<int>() + workers[1]["rows_done"].get<int>() == 30);

  const auto png = client.Get("/api/jobs/7/preview.png");
  REQUIRE(png);
  CHECK(png->get_header_value("Content-Type") == "image/png");
  CHECK(png->body == preview_png(40, 30, r.rgb, std::vector<bool>(30, true)));  // the final image
  CHECK(client.Get("/api/jobs/42/preview.png")->body == "png");  // not on the board: the fallback
  CHECK(client.Get("/api/jobs/12345/preview.png")->status == 404);

  const auto metrics = client.Get("/metrics");
  REQUIRE(metrics);
  CHECK(metrics->get_header_value("Content-Type") == "text/plain; version=0.0.4; charset=utf-8");
  CHECK(metrics->body.find("\nrayfarm_rows_done_total 30\n") != std::string::npos);
  CHECK(metrics->body.find("rayfarm_jobs{state=\"done\"} 1\n") != std::string::npos);
  CHECK(metrics->body.find("rayfarm_task_round_trip_seconds_count " + std::to_string(r.record["task_count"].get<int>()) +
                           "\n") != std::string::npos);
}
