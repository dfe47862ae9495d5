// Output files (tracer/output_file.h): refused before any work when they could
// not be written, and never left half-written under their final name.
#include <doctest/doctest.h>

#include <filesystem>

#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "tests/run_command.h"
#include "tests/test_files.h"
#include "tests/test_paths.h"
#include "tracer/error.h"
#include "tracer/image_io.h"
#include "tracer/output_file.h"
#include "tracer/text_file.h"

using namespace rayfarm;
namespace fs = std::filesystem;

using test::files_in;

namespace {

// The PID of a child that has exited and been reaped: no process has it
// (until the system hands it out again, long after this test).
pid_t dead_pid() {
  const pid_t pid = ::fork();
  if (pid == 0) ::_exit(0);
  ::waitpid(pid, nullptr, 0);
  return pid;
}

// A child that lives as long as this object: it waits for the pipe's end,
// which also comes if the test process dies first.
class LiveChild {
 public:
  LiveChild() {
    int fds[2];
    REQUIRE(::pipe(fds) == 0);
    pid_ = ::fork();
    if (pid_ == 0) {
      char c;
      ::close(fds[1]);
      while (::read(fds[0], &c, 1) != 0) {
      }
      ::_exit(0);
    }
    ::close(fds[0]);
    write_end_ = fds[1];
  }
  ~LiveChild() {
    ::close(write_end_);
    ::waitpid(pid_, nullptr, 0);
  }
  pid_t pid() const { return pid_; }

 private:
  pid_t pid_;
  int write_end_;
};

// A reaped child leaves `path`'s temporary behind, as a writer killed
// mid-write does.
void leave_temporary(const std::string& path) {
  const pid_t pid = ::fork();
  if (pid == 0) {
    AtomicOutputFile file(path);
    test::write_file(file.temp_path(), "half an image");
    ::_exit(0);  // no destructor: the temporary stays
  }
  ::waitpid(pid, nullptr, 0);
}

// A temporary of `name` as the writer `pid` names it (output_file.h), its
// N one that this process's own writes do not reach.
std::string temporary(const fs::path& dir, const std::string& name, pid_t pid, const std::string& ext) {
  return test::write_file(dir / ("." + name + "." + std::to_string(pid) + "-4242.tmp" + ext), "half an image");
}

}  // namespace

TEST_CASE("output_file: check_output_path proves the folder writable") {
  const fs::path dir = test::scratch_dir("output-check");
  CHECK_NOTHROW(check_output_path((dir / "a.png").string()));
  CHECK(files_in(dir) == 0);  // the probe file is gone
  CHECK_THROWS_WITH_AS(check_output_path((dir / "no" / "a.png").string()), doctest::Contains("no directory"),
                       InputError);
  CHECK_THROWS_WITH_AS(check_output_path("/proc/a.png"), doctest::Contains("/proc/a.png: cannot write"), InputError);
  CHECK_THROWS_WITH_AS(check_output_path(dir.string()), doctest::Contains("it is a directory"), InputError);
  fs::remove_all(dir);
}

TEST_CASE("output_file: a device, FIFO or link to one is refused, not replaced by a file") {
  const fs::path dir = test::scratch_dir("output-special");
  const std::string fifo = (dir / "pipe").string();
  REQUIRE(::mkfifo(fifo.c_str(), 0644) == 0);
  fs::create_symlink(fifo, dir / "link");
  for (const std::string& path : {fifo, (dir / "link").string()}) {
    CAPTURE(path);
    const std::string message = path + ": cannot write (not a regular file";
    CHECK_THROWS_WITH_AS(check_output_path(path), doctest::Contains(message.c_str()), InputError);
    CHECK_THROWS_WITH_AS(write_atomically(path, [](const std::string& temp) { test::write_file(temp, "x"); }),
                         doctest::Contains(message.c_str()), InputError);
    CHECK(fs::is_fifo(path));
  }
  CHECK_THROWS_WITH_AS(check_output_path("/dev/null"), doctest::Contains("/dev/null: cannot write"), InputError);
  CHECK(fs::is_character_file("/dev/null"));
  CHECK(files_in(dir) == 2);  // no temporary left
  fs::remove_all(dir);
}

TEST_CASE("output_file: a path that is a symlink replaces the file it links to, and the link stays") {
  const fs::path dir = test::scratch_dir("output-symlink");
  fs::create_directories(dir / "real");
  const std::string target = test::write_file(dir / "real" / "scene.nff", "old\n");
  fs::create_symlink(fs::path("real") / "scene.nff", dir / "link.nff");
  const std::string link = (dir / "link.nff").string();
  CHECK_NOTHROW(check_output_path(link));
  write_atomically(link, [](const std::string& temp) { test::write_file(temp, "new\n"); });
  CHECK(fs::is_symlink(link));
  CHECK(test::file_bytes(target) == "new\n");
  CHECK(files_in(dir / "real") == 1);  // no temporary left beside the target
  fs::remove_all(dir);
}

TEST_CASE("output_file: check_output_folder makes the folder and proves it writable") {
  const fs::path dir = test::scratch_dir("output-folder");
  CHECK_NOTHROW(check_output_folder((dir / "a" / "b").string()));
  CHECK(fs::is_directory(dir / "a" / "b"));
  CHECK(files_in(dir / "a" / "b") == 0);  // the probe file is gone
  const std::string file = test::write_file(dir / "file", "x");
  const std::string message = file + "/sub: cannot create folder";
  CHECK_THROWS_WITH_AS(check_output_folder(file + "/sub"), doctest::Contains(message.c_str()), InputError);
  CHECK_THROWS_WITH_AS(check_output_folder("/proc/sys"), doctest::Contains("/proc/sys: cannot write"), InputError);
  fs::remove_all(dir);
}

TEST_CASE("output_file: a write that fails midway leaves the old file and no temporary") {
  const fs::path dir = test::scratch_dir("output-atomic");
  const std::string path = (dir / "stats.json").string();
  write_text_file(path, "old\n");
  CHECK_THROWS_AS(write_atomically(path,
                                   [](const std::string& temp) {
                                     test::write_file(temp, "half a fi");  // then the writer dies
                                     throw InputError(temp + ": disk full");
                                   }),
                  InputError);
  CHECK(read_text_file(path) == "old\n");
  CHECK(files_in(dir) == 1);
  // The message names the file asked for, not the temporary.
  try {
    write_atomically(path, [](const std::string& temp) { throw InputError(temp + ": disk full"); });
  } catch (const InputError& e) {
    CHECK(std::string(e.what()) == path + ": disk full");
  }
  write_text_file(path, "new\n");
  CHECK(read_text_file(path) == "new\n");
  CHECK(files_in(dir) == 1);
  fs::remove_all(dir);
}

TEST_CASE("output_file: images are written through a temporary that keeps the extension") {
  const fs::path dir = test::scratch_dir("output-image");
  const std::vector<float> rgb(4 * 3 * 3, 0.5f);
  write_image((dir / "a.png").string(), 4, 3, rgb);
  write_image((dir / "a.exr").string(), 4, 3, rgb);
  CHECK(read_image((dir / "a.png").string()).width == 4);
  CHECK(read_image((dir / "a.exr").string()).rgb == rgb);
  CHECK(files_in(dir) == 2);
  fs::remove_all(dir);
}

TEST_CASE("output_file: a file name near the length limit is written, its temporary shortened") {
  // 250 bytes is a valid name; ".NAME.PID-N.tmp.png" beside it would not be.
  const fs::path dir = test::scratch_dir("output-long-name");
  const std::string ascii = std::string(246, 'x') + ".png";
  std::string utf8;  // two-byte characters, so a cut could land inside one
  while (utf8.size() < 245) utf8 += "\xC3\xA9";
  utf8 += ".png";
  for (const std::string& name : {ascii, utf8}) {
    CAPTURE(name.size());
    const std::string path = (dir / name).string();
    CHECK_NOTHROW(check_output_path(path));
    write_image(path, 4, 3, std::vector<float>(4 * 3 * 3, 0.5f));
    CHECK(read_image(path).width == 4);
    CHECK_NOTHROW(write_atomically(path + ".json", [](const std::string& temp) { test::write_file(temp, "{}"); }));
    CHECK(read_text_file(path + ".json") == "{}");  // 255 bytes: the longest name there is
  }
  CHECK(files_in(dir) == 4);  // two images, two JSON files, no temporary
  fs::remove_all(dir);
}

TEST_CASE("output_file: an image replaces its file, never rewrites it in place") {
  // A second name for the old file keeps the old bytes when the new image
  // arrives by rename; a write in place would change both names' bytes.
  const fs::path dir = test::scratch_dir("output-replace");
  for (const char* name : {"a.png", "a.exr"}) {
    const fs::path path = dir / name;
    write_image(path.string(), 4, 3, std::vector<float>(4 * 3 * 3, 0.25f));
    const fs::path old_name = dir / (std::string("old-") + name);
    fs::create_hard_link(path, old_name);
    write_image(path.string(), 4, 3, std::vector<float>(4 * 3 * 3, 0.75f));
    CHECK(read_image(old_name.string()).rgb[0] == doctest::Approx(0.25).epsilon(0.01));
    CHECK(read_image(path.string()).rgb[0] == doctest::Approx(0.75).epsilon(0.01));
  }
  fs::remove_all(dir);
}

TEST_CASE("output_file: `render -o /proc/x.png` fails before rendering") {
  const fs::path dir = test::scratch_dir("output-render");
  const std::string scene = test::write_file(dir / "tiny.nff", test::tiny_scene());
  const test::CommandResult r = test::run_command(test::rayfarm_exe() + " render " + scene + " -o /proc/x.png");
  CHECK(r.exit_code == 1);
  CHECK(r.output.find("/proc/x.png: cannot write") != std::string::npos);
  CHECK(r.output.find("Mrays/s") == std::string::npos);  // nothing was rendered
  fs::remove_all(dir);
}

TEST_CASE("output_file: a write removes its file's temporaries whose writer is gone, and only those") {
  const fs::path dir = test::scratch_dir("output-stale");
  const LiveChild live;  // a writer still at work
  const pid_t dead = dead_pid();
  const std::string stale = temporary(dir, "a.png", dead, ".png");
  const std::vector<std::string> kept{
      temporary(dir, "a.png", live.pid(), ".png"),
      temporary(dir, "a.png", ::getpid(), ".png"),  // this process's own
      temporary(dir, "b.png", dead, ".png"),        // another file's
      temporary(dir, "a.png", dead, ".exr"),        // not a name a.png's writer gives
      test::write_file(dir / ("a.png." + std::to_string(dead) + "-4242.tmp.png"), "not hidden"),
  };
  const std::string long_name = std::string(246, 'x') + ".png";  // its temporaries' NAME is shortened
  leave_temporary((dir / long_name).string());
  CHECK(files_in(dir) == 7);

  write_image((dir / "a.png").string(), 4, 3, std::vector<float>(4 * 3 * 3, 0.5f));
  write_image((dir / long_name).string(), 4, 3, std::vector<float>(4 * 3 * 3, 0.5f));
  CHECK_FALSE(fs::exists(stale));
  for (const std::string& path : kept) CHECK_MESSAGE(fs::exists(path), path);
  CHECK(files_in(dir) == kept.size() + 2);  // and the two images: the long name's temporary is gone too
  fs::remove_all(dir);
}
