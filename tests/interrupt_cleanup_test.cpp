// Temporaries removed on interrupt (tracer/interrupt_cleanup.h): a real
// `rayfarm render` (in-process or with --workers), `spd -o`, `fetch` or
// `submit --wait` process stopped by SIGINT, SIGTERM or SIGHUP while it writes
// its output leaves neither the temporary nor the output, and dies of the signal.
// One killed by SIGKILL cannot: the next write of its output removes what it left.
#include <doctest/doctest.h>

#include <sys/wait.h>

#include <chrono>
#include <csignal>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include <httplib.h>

#include "broker/child_process.h"
#include "service/frame_file.h"
#include "tests/test_files.h"
#include "tests/test_paths.h"

namespace fs = std::filesystem;
using namespace rayfarm;

namespace {

// The names of the files in `dir`, each followed by a space.
std::string files_in(const fs::path& dir) {
  std::string names;
  for (const auto& entry : fs::directory_iterator(dir)) names += entry.path().filename().string() + " ";
  return names;
}

// Waits up to 30 s for the render's image temporary (".NAME.PID-N.tmp.png")
// to hold bytes: the render has started writing. False if it never did.
bool wait_for_written_temporary(const fs::path& dir, const std::string& name) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (std::chrono::steady_clock::now() < end) {
    std::error_code ec;
    for (const auto& entry : fs::directory_iterator(dir, ec)) {
      const std::string file = entry.path().filename().string();
      if (file.rfind("." + name + ".", 0) == 0 && entry.file_size(ec) > 0 && !ec) return true;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return false;
}

}  // namespace

TEST_CASE("interrupt cleanup: a render stopped by SIGINT, SIGTERM or SIGHUP leaves no temporary and dies of the signal") {
  // A script's background job inherits SIGINT ignored, which the render then
  // keeps ignored; this test's render must not inherit that.
  std::signal(SIGINT, SIG_DFL);
  for (const int signal : {SIGINT, SIGTERM, SIGHUP}) {
    CAPTURE(signal);
    const fs::path dir = test::scratch_dir("interrupt");
    // Several seconds on one thread: stopped long before its last row.
    ChildProcess render(test::rayfarm_exe(), {"render", test::paper_scene("rings"), "-o", (dir / "rings.png").string(),
                                              "--width", "512", "--height", "512", "--spp", "16", "--threads", "1"});
    REQUIRE(wait_for_written_temporary(dir, "rings.png"));
    render.kill(signal);
    REQUIRE(render.wait_for(30));
    CHECK(describe_status(render.status()) == "killed by signal " + std::to_string(signal));
    CHECK(files_in(dir) == "");  // no temporary, and never the image
  }
}

TEST_CASE("interrupt cleanup: a render killed by SIGKILL leaves its temporary, and the next render of that image removes it") {
  const fs::path dir = test::scratch_dir("interrupt-kill");
  const std::string out = (dir / "rings.png").string();
  ChildProcess killed(test::rayfarm_exe(), {"render", test::paper_scene("rings"), "-o", out, "--width", "512",
                                            "--height", "512", "--spp", "16", "--threads", "1"});
  REQUIRE(wait_for_written_temporary(dir, "rings.png"));
  killed.kill(SIGKILL);  // nothing runs in the process: its temporary stays
  REQUIRE(killed.wait_for(30));
  REQUIRE(files_in(dir) != "");

  ChildProcess next(test::rayfarm_exe(), {"render", test::paper_scene("rings"), "-o", out, "--width", "16",
                                          "--height", "16", "--threads", "1"});
  REQUIRE(next.wait_for(60));
  CHECK(describe_status(next.status()) == "exit code 0");
  CHECK(files_in(dir) == "rings.png ");
}

TEST_CASE("interrupt cleanup: spd -o stopped while it writes leaves no temporary and dies of the signal") {
  const fs::path dir = test::scratch_dir("interrupt-spd");
  // Balls at size 7 is 228 MB of NFF, seconds to write: stopped long before its end.
  ChildProcess spd(test::rayfarm_exe(), {"spd", "balls", "--size", "7", "-o", (dir / "balls.nff").string()});
  REQUIRE(wait_for_written_temporary(dir, "balls.nff"));
  spd.kill(SIGTERM);
  REQUIRE(spd.wait_for(30));
  CHECK(describe_status(spd.status()) == "killed by signal " + std::to_string(SIGTERM));
  CHECK(files_in(dir) == "");
}

TEST_CASE("interrupt cleanup: render --workers stopped while it writes its image leaves no temporary and dies of the signal") {
  std::signal(SIGINT, SIG_DFL);
  const fs::path dir = test::scratch_dir("interrupt-farm");
  // A farm writes its image once the last row is in: 3072x3072 pixels of PNG
  // take a few tenths of a second to write, and are stopped long before the end.
  ChildProcess render(test::rayfarm_exe(),
                      {"render", test::paper_scene("tetra"), "-o", (dir / "tetra.png").string(), "--width", "3072",
                       "--height", "3072", "--spp", "1", "--depth", "1", "--threads", "1", "--workers", "2"});
  REQUIRE(wait_for_written_temporary(dir, "tetra.png"));
  render.kill(SIGINT);
  REQUIRE(render.wait_for(30));
  CHECK(describe_status(render.status()) == "killed by signal " + std::to_string(SIGINT));
  CHECK(files_in(dir) == "");
}

TEST_CASE("interrupt cleanup: fetch and submit --wait stopped while they write a frame leave no temporary and die of the signal") {
  // A broker of one finished job, its frame 3072x3072 pixels of noise: the
  // PNG takes the client a few tenths of a second to write, stopped long before the end.
  const int side = 3072;
  std::vector<float> rgb(static_cast<size_t>(side) * side * 3);
  uint32_t x = 1;
  for (float& v : rgb) v = float((x = x * 1664525u + 1013904223u) >> 8) / float(1u << 24);
  const std::string frame = encode_frame(side, side, rgb);
  const std::string status = R"({"id": 1, "state": "done", "frames": 1, "frames_done": 1, "rows_done": 3072,
                                 "rows_total": 3072, "resumed_rows": 0, "rerendered_rows": 0})";
  httplib::Server broker;
  broker.Post("/api/jobs", [&](const httplib::Request&, httplib::Response& res) {
    res.status = 201;
    res.set_content(status, "application/json");
  });
  broker.Get("/api/jobs/1", [&](const httplib::Request&, httplib::Response& res) {
    res.set_content(status, "application/json");
  });
  broker.Get("/api/jobs/1/frames/1", [&](const httplib::Request&, httplib::Response& res) {
    res.set_content(frame, "application/octet-stream");
  });
  const int port = broker.bind_to_any_port("127.0.0.1");
  REQUIRE(port > 0);
  std::thread serving([&broker] { broker.listen_after_bind(); });
  const std::string url = "http://127.0.0.1:" + std::to_string(port);

  const fs::path dir = test::scratch_dir("interrupt-fetch");
  const std::string out = (dir / "frame.png").string();
  for (const auto& args : {std::vector<std::string>{"fetch", "1", "--broker", url, "-o", out},
                           std::vector<std::string>{"submit", test::paper_scene("tetra"), "--broker", url, "--wait",
                                                    "-o", out}}) {
    CAPTURE(args[0]);
    ChildProcess client(test::rayfarm_exe(), args);
    REQUIRE(wait_for_written_temporary(dir, "frame.png"));
    client.kill(SIGTERM);
    REQUIRE(client.wait_for(30));
    CHECK(describe_status(client.status()) == "killed by signal " + std::to_string(SIGTERM));
    CHECK(files_in(dir) == "");
  }
  broker.stop();
  serving.join();
}
