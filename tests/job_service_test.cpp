// JobService and its state folder (JobStore): submissions checked at the door,
// jobs and their journaled rows restored after a restart (as after kill -9),
// a torn journal tail dropped, frames and records kept, the format versioned.
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

#include "protocol/log_text.h"
#include "service/frame_file.h"
#include "service/job_service.h"
#include "tests/service_scenes.h"
#include "tests/test_files.h"
#include "tracer/error.h"
#include "tracer/text_file.h"

using namespace rayfarm;
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

std::string fresh_dir(const char* name) {
  const fs::path dir = test::process_dir("service-test") / name;
  fs::remove_all(dir);
  return dir.string();
}

json submission(int frames, int priority = 0) {
  Submission s;
  for (int i = 0; i < frames; ++i) s.scenes.push_back({"f" + std::to_string(i) + ".nff", test::tiny_scene(i)});
  s.overrides.spp = 1;
  s.priority = priority;
  return submission_json(s);
}

RowBand band(int y0, int y1, float value) {
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
uint64_t job_with_two_bands_journaled(const std::string& dir) {
  JobService jobs(dir);
  const uint64_t id = jobs.submit(submission(1));
  const auto f = jobs.next_frame();
  jobs.rows_accepted(*f, band(0, 2, 0.1f));
  jobs.rows_accepted(*f, band(2, 4, 0.2f));
  return id;
}

}  // namespace

TEST_CASE("job service: a bad submission is refused with the place and changes nothing") {
  JobService jobs(fresh_dir("bad"));
  json s = submission(2);
  s["scenes"][1]["nff"] = "v\nfrom 0 0 5\n";
  CHECK_THROWS_WITH_AS(jobs.submit(s), doctest::Contains("scenes[1] (f1.nff): f1.nff:"), InputError);
  json unknown = submission(1);
  unknown["settings"]["spp_typo"] = 4;
  CHECK_THROWS_WITH_AS(jobs.submit(unknown), doctest::Contains("settings.spp_typo: unknown key"), InputError);
  json square = submission(1);
  square["settings"]["spp"] = 10;
  CHECK_THROWS_WITH_AS(jobs.submit(square), doctest::Contains("perfect square"), InputError);
  CHECK_THROWS_WITH_AS(jobs.submit(json{{"scenes", json::array()}}), doctest::Contains("scenes"), InputError);
  CHECK(jobs.list().empty());
}

TEST_CASE("job service: a scene name with control characters is refused at the door, naming the field") {
  JobService jobs(fresh_dir("control-name"));
  for (const std::string& name : {std::string("a\x1b]0;title\x07.nff"), std::string("a\0b.nff", 7),
                                  std::string("line\rover.nff"), std::string("csi\xc2\x9b" "2J.nff"),
                                  std::string("del\x7f.nff"), std::string("tab\t.nff")}) {
    CAPTURE(name);
    json s = submission(2);
    s["scenes"][1]["name"] = name;
    CHECK_THROWS_WITH_AS(jobs.submit(s),
                         ("scenes[1].name: expected no control characters (a scene's name is printed in logs and "
                          "terminals), found '" + escape_control_characters(name) + "'")
                             .c_str(),
                         InputError);
  }
  CHECK(jobs.list().empty());
  json fine = submission(1);
  fine["scenes"][0]["name"] = "sc\xc3\xa8ne \xe2\x80\x94 \xc2\xa0 1.nff";  // other UTF-8, a no-break space among it
  CHECK(jobs.submit(fine) == 1);
}

TEST_CASE("job service: a job stored with a control character in a scene name is still loaded and served") {
  const std::string dir = fresh_dir("stored-control-name");
  uint64_t id = 0;
  {
    JobService jobs(dir);
    id = jobs.submit(submission(1));
  }
  const std::string file = dir + "/jobs/" + std::to_string(id) + "/submission.json";
  json stored = read_json_file(file);
  stored["scenes"][0]["name"] = "old\x1b[1m.nff";  // accepted before names were checked
  write_text_file(file, stored.dump());
  std::vector<std::string> log;
  JobService jobs(dir, UINT64_MAX, [&](const std::string& line) { log.push_back(line); });
  CHECK(log.empty());
  CHECK(!fs::exists(dir + "/damaged"));
  CHECK(jobs.status(id)["scenes"][0] == "old\x1b[1m.nff");
  CHECK(jobs.next_frame());
}

TEST_CASE("job service: a frame larger than the broker's image limit is refused at the door") {
  JobService jobs(fresh_dir("too-large"), 1u << 20);
  json s = submission(2);
  s["settings"]["width"] = 512;
  s["settings"]["height"] = 512;  // 3 MiB of float RGB
  CHECK_THROWS_WITH_AS(jobs.submit(s),
                       "scenes[0] (f0.nff): a 512x512 image needs 3.0 MiB as float RGB; the broker's image limit is "
                       "1.0 MiB",
                       InputError);
  s["settings"]["height"] = 170;  // 0.996 MiB
  CHECK(jobs.submit(s) == 1);
}

TEST_CASE("job service: frames in order, rows journaled, restart restores the current frame") {
  const std::string dir = fresh_dir("restart");
  uint64_t id = 0;
  {
    JobService jobs(dir);
    id = jobs.submit(submission(2));
    CHECK(jobs.status(id)["state"] == "queued");
    CHECK(jobs.status(id)["rows_total"] == 48);
    auto f = jobs.next_frame();
    REQUIRE(f);
    CHECK(f->frame == 0);
    CHECK(f->settings.width == 32);
    jobs.frame_finished(*f, std::vector<float>(32 * 24 * 3, 0.5f), json{{"rows_reissued", 0}});
    f = jobs.next_frame();
    REQUIRE(f);
    CHECK(f->frame == 1);
    CHECK(!jobs.frame_after(*f));
    jobs.rows_sent(*f, 0, 4);
    jobs.rows_sent(*f, 4, 8);
    jobs.rows_sent(*f, 8, 12);
    jobs.rows_accepted(*f, band(0, 4, 0.25f));
    jobs.rows_accepted(*f, band(8, 12, 0.75f));
    CHECK(jobs.status(id)["rows_done"] == 24 + 8);
    CHECK(jobs.frame(id, 0).size() == 16 + 32 * 24 * 3 * 4);
    // A finished frame's files damaged on the server: the server's fault (500), not the client's (400).
    write_text_file(dir + "/jobs/" + std::to_string(id) + "/record-0001.json", "{ torn");
    CHECK_THROWS_WITH_AS(jobs.record(id, 0), doctest::Contains("the state folder: "), StateFault);
    const std::string frame_file = dir + "/jobs/" + std::to_string(id) + "/frame-0001.rgbf";
    const std::string frame_bytes = read_text_file(frame_file);
    fs::remove(frame_file);
    CHECK_THROWS_AS(jobs.frame(id, 0), StateFault);
    write_text_file(frame_file, frame_bytes);
    CHECK_THROWS_AS(jobs.frame(id, 1), NotReady);
    CHECK_THROWS_AS(jobs.frame(id, 2), NotFound);
  }  // the process "dies" here: nothing else is written
  JobService jobs(dir);
  const json s = jobs.status(id);
  CHECK(s["state"] == "running");
  CHECK(s["frames_done"] == 1);
  CHECK(s["rows_done"] == 24 + 8);
  CHECK(s["resumed_rows"] == 8);
  CHECK(s["rerendered_rows"] == 4);  // rows 4..8 were handed out, never returned
  const auto f = jobs.next_frame();
  REQUIRE(f);
  CHECK(f->frame == 1);
  REQUIRE(f->restored.size() == 2);
  CHECK(f->restored[0].y0 == 0);
  CHECK(f->restored[1].rgb[0] == 0.75f);
  jobs.frame_finished(*f, std::vector<float>(32 * 24 * 3, 1.0f), json{{"rows_reissued", 0}});
  CHECK(jobs.status(id)["state"] == "done");
  CHECK(!fs::exists(dir + "/jobs/" + std::to_string(id) + "/rows.journal"));
  const RgbImage img = decode_frame(jobs.frame(id, 1), "frame");
  CHECK(img.width == 32);
  CHECK(img.rgb[7] == 1.0f);
  CHECK(jobs.record(id, 1)["rows_reissued"] == 0);
}

TEST_CASE("job service: rows handed out twice before a crash (a backup copy, a lost task) count once as rendered again") {
  const std::string dir = fresh_dir("in-flight-once");
  uint64_t id = 0;
  {
    JobService jobs(dir);
    id = jobs.submit(submission(1));
    const auto f = jobs.next_frame();
    jobs.rows_sent(*f, 0, 4);
    jobs.rows_sent(*f, 4, 8);
    jobs.rows_sent(*f, 0, 4);  // a backup copy of a straggler
    jobs.rows_sent(*f, 4, 8);  // lost with its worker, handed out again
    jobs.rows_accepted(*f, band(4, 8, 0.5f));
  }  // the broker dies with rows 0..4 in flight, twice
  JobService jobs(dir);
  CHECK(jobs.status(id)["resumed_rows"] == 4);
  CHECK(jobs.status(id)["rerendered_rows"] == 4);
}

TEST_CASE("job service: a journal torn mid-record loses only that record, and the log says so") {
  const std::string dir = fresh_dir("torn");
  const uint64_t id = job_with_two_bands_journaled(dir);
  const std::string journal = dir + "/jobs/" + std::to_string(id) + "/rows.journal";
  const auto size = fs::file_size(journal);
  fs::resize_file(journal, size - 100);  // a crash in the middle of the second write
  std::vector<std::string> log;
  JobService jobs(dir, UINT64_MAX, [&](const std::string& line) { log.push_back(line); });
  REQUIRE(log.size() == 1);  // the operator hears of it
  const uint64_t kept = fs::file_size(journal);  // the first record whole
  CHECK(log[0].rfind(journal + ": dropped " + std::to_string(size - 100 - kept) +
                         " byte(s) at its end, torn or corrupt (record 3 at byte " + std::to_string(kept) +
                         ": truncated payload (",
                     0) == 0);
  CHECK(log[0].find("); any rows in them are rendered again") != std::string::npos);
  CHECK(jobs.status(id)["resumed_rows"] == 2);
  const auto f = jobs.next_frame();
  REQUIRE(f->restored.size() == 1);
  CHECK(f->restored[0].y1 == 2);
}

TEST_CASE("job service: a journal record whole by its checksum but unreadable is skipped, the others kept and logged") {
  const std::string dir = fresh_dir("unreadable-record");
  const uint64_t id = job_with_two_bands_journaled(dir);
  const std::string journal = dir + "/jobs/" + std::to_string(id) + "/rows.journal";
  const uint64_t before = fs::file_size(journal);
  {
    // Appended as a record of its own, with a valid checksum: rows 4-6 of the
    // wrong width (it says 32 pixels but carries one row's floats too few).
    JournalRecovery ignored;
    Journal j(journal, ignored);
    std::string bad = encode_journal_record(band(4, 6, 0.3f));
    bad.resize(bad.size() - 32 * 3 * sizeof(float));
    j.append(bad);
    j.append("SOMETHING ELSE");
  }
  std::vector<std::string> log;
  {
    JobService jobs(dir, UINT64_MAX, [&](const std::string& line) { log.push_back(line); });
    // Set aside whole before, its two good bands with it.
    CHECK(jobs.list().size() == 1);
    CHECK(!fs::exists(dir + "/damaged"));
    REQUIRE(log.size() == 1);
    CHECK(log[0] == journal + ": skipped 2 record(s) whole by their checksum that cannot be read as rows (record 4 " +
                        "at byte " + std::to_string(before) + ": journal row band 4:6 has the wrong size); the rows " +
                        "in them are rendered again, the other 2 record(s) kept");
    CHECK(jobs.status(id)["resumed_rows"] == 4);
    const auto f = jobs.next_frame();
    REQUIRE(f);
    REQUIRE(f->restored.size() == 2);
    CHECK(f->restored[1].y1 == 4);
    // The file is left as it was (nothing deleted), and appends go on after it.
    CHECK(fs::file_size(journal) > before);
    jobs.rows_accepted(*f, band(4, 6, 0.4f));
  }
  log.clear();
  JobService again(dir, UINT64_MAX, [&](const std::string& line) { log.push_back(line); });
  CHECK(again.status(id)["resumed_rows"] == 6);
  REQUIRE(log.size() == 1);
  CHECK(log[0].find(": skipped 2 record(s) ") != std::string::npos);
}

TEST_CASE("job service: a journal copied from another job of the same size is moved aside, its rows not mixed in") {
  const std::string dir = fresh_dir("foreign-journal");
  const uint64_t id = job_with_two_bands_journaled(dir);  // scene 0, running
  uint64_t other = 0;
  {
    JobService jobs(dir);
    json s = submission(1);
    s["scenes"][0]["nff"] = test::tiny_scene(1);  // another scene, the same size
    other = jobs.submit(s);
  }
  const std::string journal = dir + "/jobs/" + std::to_string(other) + "/rows.journal";
  fs::copy_file(dir + "/jobs/" + std::to_string(id) + "/rows.journal", journal);
  std::vector<std::string> log;
  JobService jobs(dir, UINT64_MAX, [&](const std::string& line) { log.push_back(line); });
  CHECK(jobs.status(id)["resumed_rows"] == 4);  // its own journal, kept
  CHECK(jobs.status(other)["resumed_rows"] == 0);
  CHECK(jobs.status(other)["rows_done"] == 0);
  REQUIRE(log.size() == 1);
  CHECK(log[0].rfind(journal + ": belongs to submission ", 0) == 0);
  CHECK(log[0].find(" frame 1, not to this job (submission ") != std::string::npos);
  CHECK(log[0].find("); moved aside to " + journal + ".foreign, its rows not used") != std::string::npos);
  CHECK(!fs::exists(journal));
  CHECK(fs::exists(journal + ".foreign"));
  CHECK(!fs::exists(dir + "/damaged"));
}

TEST_CASE("job service: a submission.json edited while rows are journaled has its journal moved aside") {
  const std::string dir = fresh_dir("edited-submission");
  const uint64_t id = job_with_two_bands_journaled(dir);
  const std::string folder = dir + "/jobs/" + std::to_string(id);
  json s = read_json_file(folder + "/submission.json");
  s["scenes"][0]["nff"] = test::tiny_scene(1);
  write_text_file(folder + "/submission.json", s.dump());
  std::vector<std::string> log;
  {
    JobService jobs(dir, UINT64_MAX, [&](const std::string& line) { log.push_back(line); });
    CHECK(jobs.status(id)["resumed_rows"] == 0);
    const auto f = jobs.next_frame();
    REQUIRE(f);
    CHECK(f->restored.empty());
    REQUIRE(log.size() == 1);
    CHECK(log[0].find(": belongs to submission ") != std::string::npos);
    CHECK(fs::exists(folder + "/rows.journal.foreign"));
    jobs.rows_accepted(*f, band(0, 2, 0.7f));  // a new journal, of this submission
  }
  log.clear();
  JobService again(dir, UINT64_MAX, [&](const std::string& line) { log.push_back(line); });
  CHECK(log.empty());
  CHECK(again.status(id)["resumed_rows"] == 2);
}

TEST_CASE("job service: a journal without an owner record (written before it existed) is read as before") {
  const std::string dir = fresh_dir("unowned-journal");
  const uint64_t id = job_with_two_bands_journaled(dir);
  const std::string journal = dir + "/jobs/" + std::to_string(id) + "/rows.journal";
  fs::remove(journal);
  {
    JournalRecovery ignored;
    Journal j(journal, ignored);
    j.append(encode_journal_record(band(0, 2, 0.1f)));
    j.append(encode_journal_record(band(2, 4, 0.2f)));
  }
  std::vector<std::string> log;
  JobService jobs(dir, UINT64_MAX, [&](const std::string& line) { log.push_back(line); });
  CHECK(log.empty());
  CHECK(jobs.status(id)["resumed_rows"] == 4);
}

TEST_CASE("job service: a journal of a frame saved as done (a stop before its removal) is removed, not set aside") {
  const std::string dir = fresh_dir("done-frame-journal");
  uint64_t id = 0;
  std::string kept;
  {
    JobService jobs(dir);
    id = jobs.submit(submission(2));
    const auto f = jobs.next_frame();
    jobs.rows_accepted(*f, band(0, 2, 0.1f));
    kept = read_text_file(jobs.store().journal_path(id));
    jobs.frame_finished(*f, std::vector<float>(32 * 24 * 3, 0.5f), json{{"rows_reissued", 0}});
  }
  const std::string journal = dir + "/jobs/" + std::to_string(id) + "/rows.journal";
  write_text_file(journal, kept);  // as the stop left it
  std::vector<std::string> log;
  JobService jobs(dir, UINT64_MAX, [&](const std::string& line) { log.push_back(line); });
  REQUIRE(log.size() == 1);
  CHECK(log[0] == journal + ": holds rows of frame 1, already saved as done; removed");
  CHECK(!fs::exists(journal));
  CHECK(!fs::exists(journal + ".foreign"));
  CHECK(jobs.status(id)["resumed_rows"] == 0);
}

TEST_CASE("job service: a cancelled job's journal left by a stop before its removal is removed at start, with a log line") {
  const std::string dir = fresh_dir("cancel-leftover");
  const uint64_t id = job_with_two_bands_journaled(dir);
  const std::string journal = dir + "/jobs/" + std::to_string(id) + "/rows.journal";
  const std::string kept = read_text_file(journal);
  {
    JobService jobs(dir);
    jobs.cancel(id);
  }
  write_text_file(journal, kept);  // the stop came after the status, before the journal's removal
  std::vector<std::string> log;
  JobService jobs(dir, UINT64_MAX, [&](const std::string& line) { log.push_back(line); });
  REQUIRE(log.size() == 1);
  CHECK(log[0] == journal + ": left behind by the cancelled job (a stop between its status and the journal's "
                            "removal); removed");
  CHECK(!fs::exists(journal));
  CHECK(jobs.status(id)["state"] == "cancelled");
}

TEST_CASE("job service: a journal that cannot be opened stops the start naming it, its job kept in place") {
  const std::string dir = fresh_dir("unopenable-journal");
  const uint64_t id = job_with_two_bands_journaled(dir);
  const std::string journal = dir + "/jobs/" + std::to_string(id) + "/rows.journal";
  // Immutable: opening it for writing fails (EPERM) for root too, as EACCES
  // or EROFS would; its content is as good as before.
  const int fd = ::open(journal.c_str(), O_RDONLY);
  REQUIRE(fd >= 0);
  int flags = 0;
  const bool immutable = ::ioctl(fd, FS_IOC_GETFLAGS, &flags) == 0 &&
                         (flags |= FS_IMMUTABLE_FL, ::ioctl(fd, FS_IOC_SETFLAGS, &flags) == 0);
  if (!immutable) {
    ::close(fd);
    MESSAGE("skipped: this filesystem or user cannot make a file immutable");
    return;
  }
  std::string what;
  try {
    JobService jobs(dir);
  } catch (const std::exception& e) {
    what = e.what();
  }
  flags &= ~FS_IMMUTABLE_FL;
  ::ioctl(fd, FS_IOC_SETFLAGS, &flags);
  ::close(fd);
  CHECK(what == journal + ": cannot open the journal (Operation not permitted); the job (" + dir + "/jobs/" +
                    std::to_string(id) + ") stays in place, the service does not start until its journal can be opened");
  CHECK(!fs::exists(dir + "/damaged"));
  JobService jobs(dir);  // once it can
  CHECK(jobs.status(id)["resumed_rows"] == 4);
}

TEST_CASE("job service: a journal write that fails (a full disk) is a state folder fault, as a frame's") {
  const std::string dir = fresh_dir("journal-full");
  JobService jobs(dir);
  const uint64_t id = jobs.submit(submission(1));
  const auto f = jobs.next_frame();
  jobs.rows_accepted(*f, band(0, 2, 0.1f));
  const std::string journal = jobs.store().journal_path(id);
  // No byte more fits: a write past it fails with EFBIG, as one on a full disk with ENOSPC.
  struct rlimit before {};
  ::getrlimit(RLIMIT_FSIZE, &before);
  const auto old_handler = std::signal(SIGXFSZ, SIG_IGN);
  struct rlimit full = before;
  full.rlim_cur = static_cast<rlim_t>(fs::file_size(journal));
  ::setrlimit(RLIMIT_FSIZE, &full);
  std::string what;
  try {
    jobs.rows_accepted(*f, band(2, 4, 0.2f));
  } catch (const StateFault& e) {
    what = e.what();
  } catch (const std::exception& e) {
    what = std::string("not a StateFault: ") + e.what();
  }
  ::setrlimit(RLIMIT_FSIZE, &before);
  std::signal(SIGXFSZ, old_handler);
  CHECK(what == "the state folder: " + journal + ": cannot append to the journal (File too large)");
  CHECK(jobs.status(id)["rows_done"] == 2);  // not counted
}

TEST_CASE("job service: a journal whose header a crash tore resumes its job from no rows, not set aside") {
  const std::string dir = fresh_dir("torn-header");
  uint64_t id = 0;
  {
    JobService jobs(dir);
    id = jobs.submit(submission(2));
    auto f = jobs.next_frame();
    jobs.frame_finished(*f, std::vector<float>(32 * 24 * 3, 0.5f), json{{"rows_reissued", 0}});
    f = jobs.next_frame();
    jobs.rows_sent(*f, 0, 4);
  }
  const std::string journal = dir + "/jobs/" + std::to_string(id) + "/rows.journal";
  fs::resize_file(journal, 5);  // the first write of the frame's journal, torn by a power loss
  std::vector<std::string> log;
  JobService jobs(dir, UINT64_MAX, [&](const std::string& line) { log.push_back(line); });
  REQUIRE(log.size() == 1);
  CHECK(log[0].rfind(journal + ": dropped 5 byte(s) at its end, torn or corrupt (header torn (5 of 16 bytes))", 0) ==
        0);
  CHECK(!fs::exists(dir + "/damaged"));
  const json s = jobs.status(id);
  CHECK(s["state"] == "running");
  CHECK(s["frames_done"] == 1);
  CHECK(s["resumed_rows"] == 0);
  const auto f = jobs.next_frame();
  REQUIRE(f);
  CHECK(f->frame == 1);
  CHECK(f->restored.empty());
  CHECK(jobs.frame(id, 0).size() == 16 + 32 * 24 * 3 * 4);  // the finished frame is still served
}

TEST_CASE("job service: zeros a power loss left past the journal's last record are dropped, the job resumed") {
  const std::string dir = fresh_dir("zero-tail");
  const uint64_t id = job_with_two_bands_journaled(dir);
  const std::string journal = dir + "/jobs/" + std::to_string(id) + "/rows.journal";
  const auto good = fs::file_size(journal);
  fs::resize_file(journal, good + 4096);  // the file grew, its last block never written
  std::vector<std::string> log;
  JobService jobs(dir, UINT64_MAX, [&](const std::string& line) { log.push_back(line); });
  REQUIRE(log.size() == 1);
  CHECK(log[0].rfind(journal + ": dropped 4096 byte(s) at its end, torn or corrupt (record 4 at byte " +
                         std::to_string(good) + ": zeros to the end",
                     0) == 0);
  CHECK(!fs::exists(dir + "/damaged"));
  CHECK(fs::file_size(journal) == good);
  CHECK(jobs.status(id)["resumed_rows"] == 4);
  const auto f = jobs.next_frame();
  REQUIRE(f);
  CHECK(f->restored.size() == 2);
}

TEST_CASE("job service: a journal of zeros (its header never written before a power loss) resumes from no rows") {
  const std::string dir = fresh_dir("zero-header");
  const uint64_t id = job_with_two_bands_journaled(dir);
  const std::string journal = dir + "/jobs/" + std::to_string(id) + "/rows.journal";
  const auto size = fs::file_size(journal);
  {
    std::ofstream f(journal, std::ios::binary | std::ios::trunc);
    f.write(std::string(size, '\0').data(), static_cast<std::streamsize>(size));
  }
  std::vector<std::string> log;
  JobService jobs(dir, UINT64_MAX, [&](const std::string& line) { log.push_back(line); });
  REQUIRE(log.size() == 1);
  CHECK(log[0].rfind(journal + ": dropped " + std::to_string(size) +
                         " byte(s) at its end, torn or corrupt (header all zeros: never written before a power loss)",
                     0) == 0);
  CHECK(!fs::exists(dir + "/damaged"));
  CHECK(jobs.status(id)["state"] == "running");
  CHECK(jobs.status(id)["resumed_rows"] == 0);
}

TEST_CASE("job service: priority, cancel, and jobs that outlive the process") {
  const std::string dir = fresh_dir("queue");
  {
    JobService jobs(dir);
    const uint64_t a = jobs.submit(submission(1));
    const uint64_t b = jobs.submit(submission(1));
    const uint64_t c = jobs.submit(submission(1, 10));
    CHECK(jobs.next_frame()->job == c);
    CHECK(jobs.cancel(b)["state"] == "cancelled");
    CHECK_THROWS_AS(jobs.cancel(b), NotReady);
    CHECK_THROWS_AS(jobs.cancel(99), NotFound);
    CHECK(jobs.frame_after(*jobs.next_frame())->job == a);
    CHECK(!jobs.is_running(b));
  }
  JobService jobs(dir);
  const json all = jobs.list();
  REQUIRE(all.size() == 3);
  CHECK(all[0]["state"] == "queued");
  CHECK(all[1]["state"] == "cancelled");
  CHECK(all[2]["state"] == "running");
  CHECK(jobs.submit(submission(1)) == 4);  // ids continue after a restart
}

TEST_CASE("job service: a cancel the state folder cannot take changes nothing, in memory or on disk") {
  const std::string dir = fresh_dir("cancel-unsaved");
  JobService jobs(dir);
  const uint64_t queued = jobs.submit(submission(1));
  const uint64_t running = jobs.submit(submission(1, 10));
  const auto f = jobs.next_frame();
  REQUIRE(f->job == running);
  jobs.rows_accepted(*f, band(0, 2, 0.1f));
  // Folders where the statuses go: their renames fail as on a full disk.
  const auto status_file = [&](uint64_t id) { return dir + "/jobs/" + std::to_string(id) + "/status.json"; };
  for (uint64_t id : {queued, running}) {
    fs::rename(status_file(id), status_file(id) + ".kept");
    fs::create_directories(status_file(id) + "/x");
    CHECK_THROWS_WITH_AS(jobs.cancel(id), doctest::Contains((status_file(id) + ": cannot write").c_str()), StateFault);
  }
  CHECK(jobs.status(queued)["state"] == "queued");
  CHECK(jobs.status(running)["state"] == "running");
  CHECK(jobs.is_running(running));
  const auto after = jobs.frame_after(*f);
  CHECK((after && after->job == queued));
  CHECK(fs::file_size(jobs.store().journal_path(running)) > kJournalHeaderBytes);  // its rows kept
  // Once the folder takes it, the same cancel goes through.
  for (uint64_t id : {queued, running}) {
    fs::remove_all(status_file(id));
    fs::rename(status_file(id) + ".kept", status_file(id));
    CHECK(jobs.cancel(id)["state"] == "cancelled");
    CHECK(read_json_file(status_file(id))["state"] == "cancelled");
  }
}

TEST_CASE("job service: a start, frame or failure the state folder cannot take changes nothing in memory") {
  const std::string dir = fresh_dir("change-unsaved");
  JobService jobs(dir);
  const uint64_t id = jobs.submit(submission(2));
  const std::string status_file = dir + "/jobs/" + std::to_string(id) + "/status.json";
  // A folder where the status goes: its rename fails as on a full disk.
  const auto refuse_writes = [&] {
    fs::rename(status_file, status_file + ".kept");
    fs::create_directories(status_file + "/x");
  };
  const auto take_writes = [&] {
    fs::remove_all(status_file);
    fs::rename(status_file + ".kept", status_file);
  };
  const auto unsaved = doctest::Contains((status_file + ": cannot write").c_str());
  refuse_writes();
  CHECK_THROWS_WITH_AS(jobs.next_frame(), unsaved, StateFault);
  CHECK(jobs.status(id)["state"] == "queued");
  CHECK(!jobs.is_running(id));
  take_writes();
  auto f = jobs.next_frame();
  REQUIRE(f);
  CHECK(read_json_file(status_file)["state"] == "running");
  jobs.rows_accepted(*f, band(0, 2, 0.1f));

  refuse_writes();
  CHECK_THROWS_WITH_AS(jobs.frame_finished(*f, std::vector<float>(32 * 24 * 3, 0.5f), json{{"rows_reissued", 3}}),
                       unsaved, StateFault);
  json s = jobs.status(id);
  CHECK(s["frames_done"] == 0);
  CHECK(s["rows_done"] == 2);
  CHECK(s["rerendered_rows"] == 0);
  CHECK(jobs.next_frame()->frame == 0);
  CHECK_THROWS_AS(jobs.frame(id, 0), NotReady);
  CHECK_THROWS_WITH_AS(jobs.fail(id, "bad scene"), unsaved, StateFault);
  s = jobs.status(id);
  CHECK(s["state"] == "running");
  CHECK(!s.contains("error"));
  CHECK(jobs.is_running(id));
  CHECK(fs::file_size(jobs.store().journal_path(id)) > kJournalHeaderBytes);  // its rows kept

  // Once the folder takes them, the same calls go through.
  take_writes();
  jobs.frame_finished(*f, std::vector<float>(32 * 24 * 3, 0.5f), json{{"rows_reissued", 3}});
  CHECK(read_json_file(status_file)["frames_done"] == 1);
  CHECK(jobs.status(id)["rerendered_rows"] == 3);
  jobs.fail(id, "bad scene");
  CHECK(read_json_file(status_file)["state"] == "failed");
  CHECK(jobs.status(id)["error"] == "bad scene");
}

TEST_CASE("job service: ids are never reused, also once fetched jobs' folders are removed") {
  const std::string dir = fresh_dir("ids");
  {
    JobService jobs(dir);
    for (int i = 0; i < 3; ++i) jobs.submit(submission(1));
  }
  fs::remove_all(dir + "/jobs/3");  // the latest job, fetched: its folder removed to reclaim space
  {
    JobService jobs(dir);
    CHECK(jobs.submit(submission(1)) == 4);
  }
  for (int id = 1; id <= 4; ++id) fs::remove_all(dir + "/jobs/" + std::to_string(id));
  {
    JobService jobs(dir);
    CHECK(jobs.submit(submission(1)) == 5);
  }
  write_text_file(dir + "/last-id", "five\n");
  CHECK_THROWS_WITH_AS(JobService{dir}, doctest::Contains((dir + "/last-id: expected the highest job id").c_str()), InputError);
}

TEST_CASE("job service: a job of more than 2^31 rows counts them all, also after a restart") {
  const std::string dir = fresh_dir("rows-64");
  constexpr int kFrames = 32769;  // x 65536 rows = 2^31 + 65536
  json s = submission(kFrames);
  s["settings"]["width"] = 1;
  s["settings"]["height"] = 65536;
  constexpr int64_t kRows = int64_t{kFrames} * 65536;
  {
    JobService jobs(dir);
    const uint64_t id = jobs.submit(s);
    CHECK(jobs.status(id)["rows_total"].get<int64_t>() == kRows);
  }
  JobService again(dir);
  CHECK(again.status(1)["rows_total"].get<int64_t>() == kRows);
}

TEST_CASE("job store: a second broker on a state folder in use is refused, and gets it once the first is gone") {
  const std::string dir = fresh_dir("in-use");
  {
    JobService first(dir);
    first.submit(submission(1));
    CHECK_THROWS_WITH_AS(JobService{dir}, doctest::Contains("in use by another running broker"), InputError);
    CHECK(first.list().size() == 1);
  }
  JobService next(dir);
  CHECK(next.list().size() == 1);
  CHECK(next.submit(submission(1)) == 2);
}

TEST_CASE("job store: a folder lock released a moment later (a broker just killed) is waited for, with a log line") {
  const std::string dir = fresh_dir("lock-wait");
  auto first = std::make_unique<JobStore>(dir);
  // The dying broker: its lock goes a little after the restart began.
  auto release = std::async(std::launch::async, [&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    first.reset();
  });
  std::vector<std::string> lines;
  JobStore next(dir, [&](const std::string& line) { lines.push_back(line); });
  release.get();
  REQUIRE(lines.size() == 1);
  CHECK(lines[0] == dir + ": locked by another broker; waiting up to 2000 ms for it to exit (a broker killed a "
                          "moment ago still holds it)");
}

TEST_CASE("job store: a folder lock held past the wait is refused as in use") {
  const std::string dir = fresh_dir("lock-held");
  JobStore first(dir);
  const auto t0 = std::chrono::steady_clock::now();
  CHECK_THROWS_WITH_AS(JobStore(dir, {}, std::chrono::milliseconds(200)),
                       doctest::Contains("in use by another running broker"), InputError);
  CHECK(std::chrono::steady_clock::now() - t0 >= std::chrono::milliseconds(200));
}

TEST_CASE("job store: a damaged job is set aside whole in DIR/damaged, named in the log, and the others are served") {
  const std::string dir = fresh_dir("damaged");
  {
    JobService jobs(dir);
    jobs.submit(submission(1));  // 1, kept throughout
    const auto running = jobs.submit(submission(1, 10));
    const auto f = jobs.next_frame();
    REQUIRE(f->job == running);
    jobs.rows_accepted(*f, band(0, 2, 0.1f));  // 2 has a journal
    for (int i = 0; i < 4; ++i) jobs.submit(submission(1));    // 3..6
  }
  const auto job_dir = [&](int id) { return dir + "/jobs/" + std::to_string(id); };
  const std::string status3 = read_text_file(job_dir(3) + "/status.json");
  write_text_file(job_dir(2) + "/rows.journal", "not a journal at all");
  write_text_file(job_dir(3) + "/status.json", "{\"id\": 3, ");
  write_text_file(job_dir(4) + "/submission.json", "[]");
  std::string counts = read_text_file(job_dir(5) + "/status.json");
  counts.replace(counts.find(R"("frames_done": 0)"), 16, R"("frames_done": 1)");  // queued, yet its only frame done
  write_text_file(job_dir(5) + "/status.json", counts);
  write_text_file(job_dir(6) + "/status.json", status3);  // names job 3
  std::vector<std::string> log;
  {
    JobService jobs(dir, UINT64_MAX, [&](const std::string& line) { log.push_back(line); });
    REQUIRE(jobs.list().size() == 1);
    CHECK(jobs.list()[0]["id"] == 1);
    CHECK(jobs.submit(submission(1)) == 7);  // above the ids set aside
  }
  REQUIRE(log.size() == 5);
  const auto logged = [&](int id, const std::string& reason) {
    const std::string damaged = dir + "/damaged/" + std::to_string(id);
    CHECK(fs::exists(damaged + "/status.json"));
    CHECK(fs::exists(damaged + "/submission.json"));
    CHECK(!fs::exists(job_dir(id)));
    const std::string head = job_dir(id) + ": cannot restore the job: " + reason;
    const std::string tail = "; moved whole to " + damaged + ", the other jobs go on";
    CHECK_MESSAGE(std::any_of(log.begin(), log.end(),
                              [&](const std::string& l) {
                                return l.rfind(head, 0) == 0 && l.size() >= tail.size() &&
                                       l.compare(l.size() - tail.size(), tail.size(), tail) == 0;
                              }),
                  head);
  };
  logged(2, "rows.journal: not a rayfarm journal (bad header)");
  logged(3, "status.json: invalid JSON");
  logged(4, "submission.json: ");
  logged(5, "status.json counts 1 of 1 frame(s) done, state queued");
  logged(6, "status.json: names job 3, not the job of its folder");
  CHECK(fs::exists(dir + "/damaged/2/rows.journal"));

  // After another restart: nothing more set aside, and the ids go on from
  // the highest ever used, the set-aside 7 included.
  fs::rename(job_dir(7), dir + "/damaged/7");
  log.clear();
  JobService again(dir, UINT64_MAX, [&](const std::string& line) { log.push_back(line); });
  CHECK(log.empty());
  CHECK(again.submit(submission(1)) == 8);
}

TEST_CASE("job store: a finished job's submission is not parsed at start, and its damage is said when its scenes are "
          "asked for") {
  const std::string dir = fresh_dir("finished-unparsed");
  const auto submission_file = [&](int id) { return dir + "/jobs/" + std::to_string(id) + "/submission.json"; };
  {
    JobService jobs(dir);
    const uint64_t done = jobs.submit(submission(2));  // 1
    for (int i = 0; i < 2; ++i) {
      const auto f = jobs.next_frame();
      REQUIRE(f->job == done);
      jobs.frame_finished(*f, std::vector<float>(32 * 24 * 3, 0.5f), json{{"rows_reissued", 0}});
    }
    CHECK(jobs.status(done)["scenes"] == json{"f0.nff", "f1.nff"});  // still named once its scenes are dropped
    CHECK(jobs.cancel(jobs.submit(submission(1)))["state"] == "cancelled");  // 2
    jobs.submit(submission(1));                                               // 3, queued
  }
  // 1: a scene that no longer parses (written by an older rayfarm, say): the
  // job is done, its scenes are not needed again, nor parsed at each start.
  json one = read_json_file(submission_file(1));
  one["scenes"][1]["nff"] = "v\nfrom 0 0 5\n";
  write_text_file(submission_file(1), one.dump());
  // 2: torn after its first scene's name.
  const std::string two = read_text_file(submission_file(2));
  write_text_file(submission_file(2), two.substr(0, two.find("\"nff\"") + 10));
  std::vector<std::string> log;
  {
    JobService jobs(dir, UINT64_MAX, [&](const std::string& line) { log.push_back(line); });
    CHECK(log.empty());
    CHECK(!fs::exists(dir + "/damaged"));
    const json all = jobs.list();
    REQUIRE(all.size() == 3);
    CHECK(all[0]["state"] == "done");
    CHECK(all[0]["scene"] == "f0.nff");
    CHECK(all[1]["state"] == "cancelled");
    CHECK(all[1]["scene"] == "f0.nff");  // read from the file's first bytes
    CHECK(all[2]["state"] == "queued");
    CHECK(jobs.status(1)["scenes"] == json{"f0.nff", "f1.nff"});
    CHECK(decode_frame(jobs.frame(1, 1), "frame").rgb[0] == 0.5f);
    CHECK(log.empty());

    // What needs the file names it and what it found; the job's status is still
    // answered (a client waiting for it goes on to its frames), logged once.
    for (int ask = 0; ask < 2; ++ask) {
      const json s = jobs.status(2);
      CHECK(s["state"] == "cancelled");
      CHECK(!s.contains("scenes"));
      CHECK(s["submission_error"].get<std::string>().rfind(submission_file(2) + ": invalid JSON: ", 0) == 0);
    }
    REQUIRE(log.size() == 1);
    CHECK(log[0].rfind(submission_file(2) + ": invalid JSON: ", 0) == 0);
    CHECK(log[0].find("; job 2 (cancelled) is still served, its status, frames and records, without its scene names") !=
          std::string::npos);
  }

  // One that disagrees with its status, or is gone.
  one["scenes"].erase(1);
  write_text_file(submission_file(1), one.dump());
  fs::remove(submission_file(2));
  JobService again(dir, UINT64_MAX, [&](const std::string& line) { log.push_back(line); });
  CHECK(again.status(1)["submission_error"] ==
        submission_file(1) + ": holds 1 scene(s), status.json counts 2 frame(s)");
  CHECK(again.status(2)["submission_error"] == submission_file(2) + ": missing, not a regular file");
  CHECK(!again.list()[1].contains("scene"));
}

TEST_CASE("job service: a submission the state folder cannot take leaves no job folder behind") {
  const std::string dir = fresh_dir("submit-fails");
  JobService jobs(dir);
  CHECK(jobs.submit(submission(1)) == 1);
  // Files past a few bytes cannot be written (as on a full disk): the
  // submission's file fails after its folder was made.
  const auto old_handler = std::signal(SIGXFSZ, SIG_IGN);
  rlimit old_limit{};
  REQUIRE(::getrlimit(RLIMIT_FSIZE, &old_limit) == 0);
  rlimit small = old_limit;
  small.rlim_cur = 16;
  REQUIRE(::setrlimit(RLIMIT_FSIZE, &small) == 0);
  CHECK_THROWS(jobs.submit(submission(1)));
  ::setrlimit(RLIMIT_FSIZE, &old_limit);
  std::signal(SIGXFSZ, old_handler);
  // Before: an empty jobs/2 stayed behind.
  CHECK(!fs::exists(dir + "/jobs/2"));
  CHECK(jobs.list().size() == 1);
  CHECK(jobs.submit(submission(1)) == 3);  // the id 2 is not given out again
}

TEST_CASE("job store: a job folder a stopped broker left without its status is removed at start, and logged") {
  const std::string dir = fresh_dir("incomplete");
  { JobService(dir).submit(submission(1)); }
  const auto job_dir = [&](int id) { return dir + "/jobs/" + std::to_string(id); };
  fs::create_directories(job_dir(2));  // stopped before the submission was written
  fs::create_directories(job_dir(3));  // after it, before the status, a temporary left too
  write_text_file(job_dir(3) + "/submission.json", read_text_file(job_dir(1) + "/submission.json"));
  write_text_file(job_dir(3) + "/.status.123-0.tmp.json", "{");
  std::vector<std::string> log;
  {
    JobService jobs(dir, UINT64_MAX, [&](const std::string& line) { log.push_back(line); });
    CHECK(jobs.list().size() == 1);
  }
  // Before: both stayed in jobs/ for ever, unlisted and unlogged.
  CHECK(!fs::exists(job_dir(2)));
  CHECK(!fs::exists(job_dir(3)));
  CHECK(fs::exists(job_dir(1) + "/status.json"));
  REQUIRE(log.size() == 2);
  const auto logged = [&](int id, const std::string& held) {
    const std::string line = job_dir(id) + ": a job folder holding " + held +
                             ", without status.json: the broker stopped while creating the job, before answering "
                             "its submission; removed";
    CHECK_MESSAGE(std::find(log.begin(), log.end(), line) != log.end(), line);
  };
  logged(2, "nothing");
  logged(3, "only its submission");
  log.clear();
  JobService again(dir, UINT64_MAX, [&](const std::string& line) { log.push_back(line); });
  CHECK(log.empty());
}

TEST_CASE("job store: temporaries a killed broker left mid-write are removed at start, and logged") {
  const std::string dir = fresh_dir("temporaries");
  { JobService(dir).submit(submission(1)); }
  const std::string job = dir + "/jobs/1";
  // Killed while renaming a frame into place, a status, last-id: each stays
  // hidden beside its file, the frame's as large as the frame.
  const std::vector<std::string> left = {job + "/.frame-0001.rgbf.4242-7.tmp.rgbf",
                                         job + "/.status.json.4242-9.tmp.json", dir + "/.last-id.4242-3.tmp"};
  for (const std::string& path : left) write_text_file(path, std::string(4096, 'x'));
  write_text_file(job + "/.notes", "the operator's");  // not a temporary: kept
  std::vector<std::string> log;
  {
    JobService jobs(dir, UINT64_MAX, [&](const std::string& line) { log.push_back(line); });
    CHECK(jobs.status(1)["state"] == "queued");
  }
  // Before: each stayed for good, one more frame's worth of disk per crash.
  for (const std::string& path : left) CHECK_MESSAGE(!fs::exists(path), path);
  CHECK(fs::exists(job + "/.notes"));
  CHECK(fs::exists(job + "/status.json"));
  REQUIRE(log.size() == 3);
  CHECK(log[0] == dir + "/.last-id.4242-3.tmp: left by a broker that stopped while writing last-id; removed");
  CHECK(log[1] == job + "/.frame-0001.rgbf.4242-7.tmp.rgbf: left by a broker that stopped while writing "
                        "frame-0001.rgbf; removed");
  CHECK(log[2] == job + "/.status.json.4242-9.tmp.json: left by a broker that stopped while writing status.json; "
                        "removed");
}

TEST_CASE("job store: a FIFO in the state folder is refused naming it, the job set aside, never blocking the start") {
  const std::string dir = fresh_dir("fifo");
  {
    JobService jobs(dir);
    for (int i = 0; i < 4; ++i) jobs.submit(submission(1));
  }
  const auto job_dir = [&](int id) { return dir + "/jobs/" + std::to_string(id); };
  const std::vector<std::string> fifos = {job_dir(1) + "/status.json", job_dir(2) + "/submission.json",
                                          job_dir(3) + "/frame-0001.rgbf"};
  for (const std::string& f : fifos) {
    fs::remove(f);
    REQUIRE(::mkfifo(f.c_str(), 0600) == 0);
  }
  std::vector<std::string> log;
  json served;
  CHECK(starts_without_blocking(
      [&] { served = JobService(dir, UINT64_MAX, [&](const std::string& line) { log.push_back(line); }).list(); },
      fifos));
  REQUIRE(served.size() == 1);
  CHECK(served[0]["id"] == 4);
  std::sort(log.begin(), log.end());
  REQUIRE(log.size() == 3);
  CHECK(log[0] == job_dir(1) + ": cannot restore the job: status.json: a FIFO, not a regular file; moved whole to " +
                      dir + "/damaged/1, the other jobs go on");
  CHECK(log[1].rfind(job_dir(2) + ": cannot restore the job: submission.json: a FIFO, not a regular file;", 0) == 0);
  CHECK(log[2].rfind(job_dir(3) + ": cannot restore the job: frame-0001.rgbf: a FIFO, not a regular file;", 0) == 0);
  CHECK(fs::is_fifo(dir + "/damaged/2/submission.json"));

  // The folder's own files stop the start, naming the file, as a damaged one would.
  for (const char* name : {"last-id", "rayfarm-state.json"}) {
    const std::string file = dir + "/" + name;
    fs::remove(file);
    REQUIRE(::mkfifo(file.c_str(), 0600) == 0);
    std::string refused;
    CHECK(starts_without_blocking(
        [&] {
          try {
            JobService jobs(dir);
          } catch (const InputError& e) {
            refused = e.what();
          }
        },
        {file}));
    CHECK(refused == file + ": a FIFO, not a regular file");
    fs::remove(file);
  }
}

TEST_CASE("job store: a symbolic link in the state folder is never written through, its job set aside and named") {
  const std::string dir = fresh_dir("symlink"), outside = dir + "-outside";
  fs::remove_all(outside);
  fs::create_directories(outside + "/job");
  const auto job_dir = [&](int id) { return dir + "/jobs/" + std::to_string(id); };
  {
    JobService jobs(dir);
    const uint64_t id = jobs.submit(submission(1));
    // Placed while the job runs, before its first row: the journal is opened on that row.
    fs::create_symlink(outside + "/rows.journal", job_dir(1) + "/rows.journal");
    const auto f = jobs.next_frame();
    REQUIRE(f->job == id);
    CHECK_THROWS_WITH_AS(jobs.rows_accepted(*f, band(0, 2, 0.1f)),
                         ("the state folder: " + job_dir(1) +
                          "/rows.journal: a symbolic link, not followed; the journal is a file of its own")
                             .c_str(),
                         StateFault);
    jobs.submit(submission(1));  // 2: a folder elsewhere linked in its place
    jobs.submit(submission(1));  // 3: kept
  }
  CHECK(!fs::exists(outside + "/rows.journal"));
  for (const auto& entry : fs::directory_iterator(job_dir(2))) fs::copy(entry.path(), outside + "/job");
  fs::remove_all(job_dir(2));
  fs::create_directory_symlink(outside + "/job", job_dir(2));
  std::vector<std::string> log;
  JobService jobs(dir, UINT64_MAX, [&](const std::string& line) { log.push_back(line); });
  REQUIRE(jobs.list().size() == 1);
  CHECK(jobs.list()[0]["id"] == 3);
  std::sort(log.begin(), log.end());
  REQUIRE(log.size() == 2);
  CHECK(log[0] == job_dir(1) + ": cannot restore the job: rows.journal: a symbolic link (to " + outside +
                      "/rows.journal), not a regular file; moved whole to " + dir + "/damaged/1, the other jobs go on");
  CHECK(log[1] == job_dir(2) + ": cannot restore the job: a symbolic link (to " + outside +
                      "/job), not a folder; moved whole to " + dir + "/damaged/2, the other jobs go on");
  CHECK(fs::is_symlink(dir + "/damaged/2"));  // the link moved, not what it points to
  CHECK(fs::exists(outside + "/job/status.json"));
  CHECK(!fs::exists(outside + "/rows.journal"));
  fs::remove_all(outside);
}

TEST_CASE("job store: a note like service.json replaces a symbolic link in its place, never writing through it") {
  const std::string dir = fresh_dir("note-link"), outside = dir + "-outside.json";
  write_text_file(outside, "kept\n");
  JobStore store(dir);
  fs::create_symlink(outside, dir + "/service.json");
  store.write_note("service.json", "{}\n");
  CHECK(fs::is_regular_file(fs::symlink_status(dir + "/service.json")));
  CHECK(read_text_file(dir + "/service.json") == "{}\n");
  CHECK(read_text_file(outside) == "kept\n");
  fs::remove(outside);
}

TEST_CASE("job store: a DIR/jobs that is not a folder is refused naming DIR/jobs and what it is") {
  const std::string dir = fresh_dir("jobs-not-a-folder"), jobs = dir + "/jobs";
  fs::create_directories(dir);
  write_text_file(jobs, "");
  CHECK_THROWS_WITH_AS(JobStore{dir}, (jobs + ": a regular file, not a folder").c_str(), InputError);
  fs::remove(jobs);
  fs::create_symlink(dir + "/nowhere", jobs);
  CHECK_THROWS_WITH_AS(JobStore{dir}, (jobs + ": a symbolic link (to " + dir + "/nowhere), not a folder").c_str(),
                       InputError);
  CHECK(!fs::exists(dir + "/nowhere"));
  fs::remove(jobs);
  { JobStore store(dir); }  // made when missing
  CHECK(fs::is_directory(fs::symlink_status(jobs)));
}

TEST_CASE("job store: the state folder's format is versioned") {
  const std::string dir = fresh_dir("version");
  { JobStore store(dir); }
  write_text_file(dir + "/rayfarm-state.json", R"({"format": "rayfarm-state", "version": 2})");
  CHECK_THROWS_WITH_AS(JobStore{dir}, doctest::Contains("state format version 2"), InputError);
}

TEST_CASE("job service: a marker removed while the service runs is written back at the next submission or frame") {
  const std::string dir = fresh_dir("marker-removed"), marker = dir + "/rayfarm-state.json";
  std::vector<std::string> log;
  uint64_t id = 0;
  {
    JobService jobs(dir, UINT64_MAX, [&](const std::string& line) { log.push_back(line); });
    const std::string original = read_text_file(marker);
    fs::remove(marker);
    id = jobs.submit(submission(2));
    // Noticed only at the next start before, which then refused the folder, jobs and all.
    CHECK(read_text_file(marker) == original);
    REQUIRE(log.size() == 1);
    CHECK(log[0] == marker + ": removed while the service ran; written back (without it the next start would "
                             "refuse the folder)");
    const auto f = jobs.next_frame();
    CHECK(log.size() == 1);  // present: nothing to say
    jobs.frame_finished(*f, std::vector<float>(32 * 24 * 3, 0.5f), json{{"rows_reissued", 0}});
    fs::remove(marker);
    REQUIRE(jobs.next_frame());  // between frames too
    CHECK(fs::exists(marker));
    CHECK(log.size() == 2);
  }
  JobService again(dir);
  CHECK(again.status(id)["frames_done"] == 1);
}

TEST_CASE("job store: a folder with jobs but no rayfarm-state.json is refused, its files left where they are") {
  const std::string dir = fresh_dir("no-marker"), marker = dir + "/rayfarm-state.json";
  // Another program's folder that happens to have a jobs/: nothing in it is moved to damaged/.
  fs::create_directories(dir + "/jobs/photos");
  write_text_file(dir + "/jobs/photos/a.txt", "kept\n");
  CHECK_THROWS_WITH_AS(JobService{dir}, doctest::Contains((marker + ": missing, though " + dir +
                                                           " holds jobs/ (1 entry): not a rayfarm state folder")
                                                              .c_str()),
                       InputError);
  CHECK(!fs::exists(marker));
  CHECK(!fs::exists(dir + "/damaged"));
  CHECK(read_text_file(dir + "/jobs/photos/a.txt") == "kept\n");
  fs::remove_all(dir);
  // A state folder whose marker was removed: its jobs are not taken over silently.
  uint64_t id = 0;
  {
    JobService jobs(dir);
    id = jobs.submit(submission(1));
  }
  fs::remove(marker);
  CHECK_THROWS_WITH_AS(JobService{dir}, doctest::Contains("holds jobs/ (1 entry), last-id: "), InputError);
  write_text_file(marker, R"({"format": "rayfarm-state", "version": 1})");  // as the message says
  CHECK(JobService{dir}.status(id)["state"] == "queued");
  // A first start that died before writing the marker left an empty jobs/ only: taken.
  fs::remove_all(dir);
  fs::create_directories(dir + "/jobs");
  { JobStore store(dir); }
  CHECK(fs::exists(marker));
}
