// JobService and its state folder (JobStore): submissions checked at the door,
// jobs and their journaled rows restored after a restart (as after kill -9),
// a torn journal tail dropped, frames and records kept, the format versioned.
#include <doctest/doctest.h>

#include <tuple>
#include <vector>

#include "tests/job_state_fixture.h"

using namespace rayfarm;
using namespace rayfarm::test;
namespace fs = std::filesystem;
using nlohmann::json;

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

TEST_CASE("job service: a setting out of range is refused naming the field written, not the first scene") {
  JobService jobs(fresh_dir("bad-setting"));
  for (const auto& [key, value, reason] : std::vector<std::tuple<std::string, json, std::string>>{
           {"width", 0, "settings.width: width must be between 1 and 65536, found 0"},
           {"height", 70000, "settings.height: height must be between 1 and 65536, found 70000"},
           {"spp", 10, "settings.spp: spp must be a perfect square"},
           {"depth", 65, "settings.depth: depth must be between 1 and 64, found 65"},
           {"adaptive_contrast", -1, "settings.adaptive_contrast: adaptive contrast must be"},
           {"cutoff", 2, "settings.cutoff: cutoff must be between 0 and 1, found 2"}}) {
    CAPTURE(key);
    json s = submission(2);
    s["settings"][key] = value;
    CHECK_THROWS_WITH_AS(jobs.submit(s), doctest::Contains(reason.c_str()), InputError);
  }
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
    // Quoted as it is, a NUL as U+FFFD: what prints the reason escapes it, once.
    std::string quoted = name;
    if (const size_t nul = quoted.find('\0'); nul != std::string::npos) quoted.replace(nul, 1, "\xef\xbf\xbd");
    CHECK_THROWS_WITH_AS(jobs.submit(s),
                         ("scenes[1].name: expected no control characters (a scene's name is printed in logs and "
                          "terminals), found '" + quoted + "'")
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
