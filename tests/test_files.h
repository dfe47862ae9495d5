// Small files for tests: a per-process scratch folder and a tiny scene that
// exercises every code path of a render (two spheres, a polygon, a light).
#pragma once

#include <sys/resource.h>
#include <unistd.h>

#include <csignal>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <system_error>
#include <vector>

namespace rayfarm::test {

// The folders process_dir() made, removed when the test process exits
// normally (each test case runs in a process of its own), so that test runs
// leave nothing in the temp dir. Children the tests start exec or _exit, and
// never run this.
class ProcessDirs {
 public:
  static void remember(const std::filesystem::path& dir) {
    auto& dirs = all().dirs_;
    if (dirs.empty() || dirs.back() != dir) dirs.push_back(dir);
  }

 private:
  ProcessDirs() = default;
  ~ProcessDirs() {
    std::error_code ignored;
    for (const auto& dir : dirs_) std::filesystem::remove_all(dir, ignored);
  }
  static ProcessDirs& all() {
    static ProcessDirs dirs;
    return dirs;
  }
  std::vector<std::filesystem::path> dirs_;
};

// A folder under the system temp dir, unique per test process and tag, kept
// (with what tests put in it) until the process exits.
inline std::filesystem::path process_dir(const std::string& tag) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("rayfarm-" + tag + "-" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  ProcessDirs::remember(dir);  // also a folder an earlier process of the same pid left
  return dir;
}

// process_dir(tag), emptied.
inline std::filesystem::path scratch_dir(const std::string& tag) {
  const std::filesystem::path dir = process_dir(tag);
  for (const auto& entry : std::filesystem::directory_iterator(dir)) std::filesystem::remove_all(entry.path());
  return dir;
}

inline std::string write_file(const std::filesystem::path& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
  return path.string();
}

// A file's bytes; empty if it cannot be read.
inline std::string file_bytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// How many entries `dir` holds (temporaries left behind show up here).
inline size_t files_in(const std::filesystem::path& dir) {
  size_t n = 0;
  for ([[maybe_unused]] const auto& entry : std::filesystem::directory_iterator(dir)) ++n;
  return n;
}

// 16x12 pixels: renders in milliseconds.
inline const char* tiny_scene() {
  return "b 0.1 0.2 0.3\nv\nfrom 0 -4 1\nat 0 0 0\nup 0 0 1\nangle 40\nhither 0.01\nresolution 16 12\n"
         "l 3 -3 5\nf 1 0.5 0.5 0.8 0.3 20 0 1\ns -0.6 0 0 0.5\ns 0.6 0 0 0.5\n"
         "f 0.8 0.8 0.8 1 0 0 0 1\np 4\n-3 -3 -0.5\n3 -3 -0.5\n3 3 -0.5\n-3 3 -0.5\n";
}

// The soft file-size limit lowered for one scope: a write beyond it fails with
// EFBIG (SIGXFSZ, which would kill the process, is ignored meanwhile).
class FileSizeLimit {
 public:
  explicit FileSizeLimit(rlim_t bytes) {
    getrlimit(RLIMIT_FSIZE, &saved_);
    previous_ = std::signal(SIGXFSZ, SIG_IGN);
    rlimit lowered = saved_;
    lowered.rlim_cur = bytes;
    setrlimit(RLIMIT_FSIZE, &lowered);
  }
  ~FileSizeLimit() {
    setrlimit(RLIMIT_FSIZE, &saved_);
    std::signal(SIGXFSZ, previous_);
  }

 private:
  rlimit saved_{};
  void (*previous_)(int) = nullptr;
};

}  // namespace rayfarm::test
