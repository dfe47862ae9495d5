// JobStore: the state folder itself: its lock, its marker and version, jobs
// set aside whole when damaged, temporaries and links a crash or an operator
// left, finished jobs served without their scenes.
#include <doctest/doctest.h>

#include "tests/job_state_fixture.h"

using namespace rayfarm;
using namespace rayfarm::test;
namespace fs = std::filesystem;
using nlohmann::json;

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

TEST_CASE("job store: a submission.json cut inside its scene is logged in a short line naming file and place") {
  // The JSON library quoted the scene it was reading whole: the start logged
  // a line as long as the scene.
  const std::string dir = fresh_dir("cut-submission");
  Submission big;
  big.scenes.push_back({"big.nff", test::tiny_scene(0) + "# " + std::string(50000, 'x') + "\n"});
  big.overrides.spp = 1;
  { JobService(dir).submit(submission_json(big)); }
  const std::string path = dir + "/jobs/1/submission.json";
  const std::string text = read_text_file(path);
  write_text_file(path, text.substr(0, text.size() / 2));
  std::vector<std::string> log;
  { JobService jobs(dir, UINT64_MAX, [&](const std::string& line) { log.push_back(line); }); }
  REQUIRE(log.size() == 1);
  CAPTURE(log[0].substr(0, 300));
  CHECK(log[0].rfind(dir + "/jobs/1: cannot restore the job: submission.json: invalid JSON: ", 0) == 0);
  CHECK(log[0].find("parse error at line 1, column ") != std::string::npos);
  CHECK(log[0].size() < 2 * dir.size() + 400);
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
