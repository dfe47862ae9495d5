// Helpers shared by the JobService and JobStore tests: a state folder per
// case, small submissions and journaled bands, a start that a FIFO cannot block.
#pragma once

#include <doctest/doctest.h>

#include <fcntl.h>
#include <linux/fs.h>
#include <sys/ioctl.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <future>
#include <memory>
#include <thread>

#include "service/frame_file.h"
#include "service/job_service.h"
#include "tests/service_scenes.h"
#include "tests/test_files.h"
#include "tracer/error.h"
#include "tracer/log_text.h"
#include "tracer/text_file.h"

namespace rayfarm::test {

namespace fs = std::filesystem;
using nlohmann::json;

inline std::string fresh_dir(const char* name) {
  const fs::path dir = test::process_dir("service-test") / name;
  fs::remove_all(dir);
  return dir.string();
}

inline json submission(int frames, int priority = 0) {
  Submission s;
  for (int i = 0; i < frames; ++i) s.scenes.push_back({"f" + std::to_string(i) + ".nff", test::tiny_scene(i)});
  s.overrides.spp = 1;
  s.priority = priority;
  return submission_json(s);
}

inline RowBand band(int y0, int y1, float value) {
  RowBand b;
  b.y0 = y0;
  b.y1 = y1;
  b.width = 32;
  b.stats.eye = static_cast<uint64_t>((y1 - y0) * 32);
  b.rgb.assign(static_cast<size_t>((y1 - y0) * 32 * 3), value);
  return b;
}

// Runs `start` (which opens a state folder) on a thread of its own. Should it
// still be at work after 10 s it is taken as blocked on one of `fifos`, which
// are then opened for writing and closed, so that a reader blocked on them
// sees an empty file and the thread ends. Returns whether it ended by itself.
template <class Start> bool starts_without_blocking(Start start, const std::vector<std::string>& fifos) {
  auto started = std::async(std::launch::async, start);
  if (started.wait_for(std::chrono::seconds(10)) == std::future_status::ready) {
    started.get();
    return true;
  }
  while (started.wait_for(std::chrono::milliseconds(50)) != std::future_status::ready)
    for (const std::string& fifo : fifos) {
      const int fd = ::open(fifo.c_str(), O_WRONLY | O_NONBLOCK);
      if (fd >= 0) ::close(fd);
    }
  return false;
}

// A one-frame job in `dir` whose rows 0-4 are journaled as two bands, by a
// service that then stopped: its id.
inline uint64_t job_with_two_bands_journaled(const std::string& dir) {
  JobService jobs(dir);
  const uint64_t id = jobs.submit(submission(1));
  const auto f = jobs.next_frame();
  jobs.rows_accepted(*f, band(0, 2, 0.1f));
  jobs.rows_accepted(*f, band(2, 4, 0.2f));
  return id;
}

}  // namespace rayfarm::test
