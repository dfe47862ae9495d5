// A bad job fails, the fleet survives: scenes whose numbers would break the
// tracer are refused or fail cleanly (never abort), a worker that cannot render
// a job reports `job_failed` and stays up, and the broker fails the job with
// the reason instead of waiting forever. Real processes and sockets.
#include <doctest/doctest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <mutex>
#include <optional>
#include <utility>
#include <string>
#include <thread>
#include <vector>

#include "broker/broker.h"
#include "tests/farm_peers.h"
#include "tests/run_command.h"
#include "tests/test_files.h"
#include "tracer/embree_scene.h"
#include "tracer/nff_reader.h"
#include "tracer/renderer.h"

using namespace rayfarm;
using namespace rayfarm::test;
namespace fs = std::filesystem;

namespace {

const std::string kView = "v\nfrom 0 0 5\nat 0 0 0\nup 0 1 0\nangle 45\nhither 0\nresolution 16 16\nl 0 5 0\n";

FarmJob job_of(const std::string& scene) {
  RenderSettings s;
  s.width = s.height = 16;
  s.spp = 4;
  s.threads = 1;
  return {scene, "scene.nff", s};
}

}  // namespace

TEST_CASE("job failure: a light at 1e19 is refused with file:line, not an abort") {
  const fs::path dir = scratch_dir("far-light");
  const std::string scene = write_file(dir / "far.nff", kView + "l 0 0 1e19\nf 1 1 1 1 0 1 0 1\ns 0 0 0 1\n");
  const CommandResult r = run_command(rayfarm_exe() + " render " + scene + " -o " + (dir / "x.png").string());
  CHECK(r.exit_code == 1);  // was 134: Embree's ray.valid() assertion
  CHECK(r.output.find(scene + ":9: number \"1e19\" after 'l' is beyond +-1e+16") != std::string::npos);
  // The limit itself renders.
  write_file(dir / "near.nff", kView + "l 0 0 1e16\nf 1 1 1 1 0 1 0 1\ns 0 0 0 1\n");
  CHECK(run_command(rayfarm_exe() + " render " + (dir / "near.nff").string() + " -o " + (dir / "x.png").string())
            .exit_code == 0);
  fs::remove_all(dir);
}

TEST_CASE("job failure: rays Embree would abort on are refused at the one Embree seam") {
  // Embree's ray.valid() is an assertion in Debian's build: such a ray must
  // never reach it. The tracer's exact primitive tests keep scenes within
  // kMaxSceneMagnitude far from this guard; it is the last line.
  CHECK_NOTHROW(EmbreeScene::check_ray({1e16, -1e16, 0}, {1e17, 0, -1}));
  CHECK_THROWS_WITH_AS(EmbreeScene::check_ray({0, 0, 2e18}, {0, 0, 1}),
                       doctest::Contains("make a ray the tracer cannot take"), InputError);
  CHECK_THROWS_AS(EmbreeScene::check_ray({0, 0, 0}, {std::nan(""), 0, 1}), InputError);
  CHECK_THROWS_AS(EmbreeScene::check_ray({-HUGE_VAL, 0, 0}, {0, 0, 1}), InputError);
  // Packets: the fill kernel's test, then the same message.
  Scene scene;
  scene.camera.width = scene.camera.height = 8;
  scene.spheres.push_back({{0, 0, 5}, 1, 0});
  scene.materials.push_back({});
  const EmbreeScene es(scene, {});
  Vec3 orgs[EmbreeScene::kPacket], dirs[EmbreeScene::kPacket];
  for (Vec3& d : dirs) d = {0, 0.01, 10};  // t in (0, 1) crosses the sphere
  dirs[11].x = std::nan("");
  TraceHit hits[EmbreeScene::kPacket];
  bool blocked[EmbreeScene::kPacket];
  CHECK_THROWS_WITH_AS(es.intersect_packet(orgs, dirs, 16, hits), doctest::Contains("cannot take"), InputError);
  CHECK_THROWS_WITH_AS(es.occluded_packet(orgs, dirs, 12, blocked), doctest::Contains("cannot take"), InputError);
  CHECK_NOTHROW(es.occluded_packet(orgs, dirs, 11, blocked));  // lane 11 is not the packet's
  CHECK(blocked[0]);
}

TEST_CASE("job failure: a worker reports a job it cannot render, the broker fails it at once, the worker serves on") {
  LogCapture log;
  Broker broker(test_broker_config(1), log.sink());
  ChildProcess worker = spawn_worker(broker.endpoint(), "w1");
  // The broker does not parse what it is given here; the worker's parse fails.
  CHECK_THROWS_WITH_AS(broker.run(job_of(kView + "s 0 0\n"), deadline(30)),
                       doctest::Contains("failed on the workers: scene.nff:9: expected 4 numbers after 's'"),
                       FarmJobFailed);
  CHECK(log.count("worker w1#1 cannot render job") == 1);
  CHECK(worker.running());
  const FarmJob good = job_of(kView + "f 1 1 1 1 0 1 0 1\ns 0 0 0 1\n");
  CHECK(broker.run(good, deadline(30)).rgb == in_process(good));  // same worker, next job
  CHECK(worker.running());
}

TEST_CASE("job failure: a worker's own failure fails the job only when a second worker fails too, named alike or not") {
  // Twins sharing a name were counted by name (and key): their two failures
  // counted as one, both left the job's dispatch, and the broker waited for a third.
  for (const auto& [name_a, name_b] : {std::pair<std::string, std::string>{"a", "b"}, {"twin", "twin"}}) {
    CAPTURE(name_b);
    LogCapture log;
    BrokerConfig cfg = test_broker_config(1);
    cfg.liveness = 20;
    Broker broker(cfg, log.sink());
    std::optional<std::string> failure;
    struct Farm {
      std::thread thread;
      ~Farm() { thread.join(); }
    } farm{std::thread([&] {
      try {
        broker.run(job_of(kView + "s 0 0 0 1\n"), deadline(20));
      } catch (const std::exception& e) {
        failure = e.what();
      }
    })};
    zmq::context_t ctx(1);
    RawPeer a(ctx, broker.endpoint()), b(ctx, broker.endpoint());
    const JobSpec spec = a.join(name_a, 1);
    b.join(name_b, 1);
    REQUIRE(a.wait_for<TaskAssign>(5));
    a.send_message(JobFailed{spec.job, FailureScope::worker, "out of memory"});
    a.idle(0.5);
    CHECK_FALSE(failure);  // one sick machine is not a bad job; a's task went back
    CHECK(log.count("worker " + name_a + "#1 cannot render job " + std::to_string(spec.job) +
                    " (worker): out of memory; requeued 1 task(s)") == 1);
    b.send_message(JobFailed{spec.job, FailureScope::worker, "out of memory"});
    farm.thread.join();
    farm.thread = std::thread([] {});
    REQUIRE(failure);  // the twins' before: the deadline's "farm test deadline passed"
    CHECK(failure->find("out of memory (and 1 other worker(s) failed)") != std::string::npos);
    CHECK(log.count("worker " + name_b + "#2 cannot render job") == 1);
  }
}

TEST_CASE("job failure: rejection lines the rate limit held back are counted in the log before the failure is") {
  // A job that ended done said its held-back count first; a failed one did
  // not, and a one-shot broker exited with the count never said.
  LogCapture log;
  BrokerConfig cfg = test_broker_config(1);
  cfg.liveness = 20;
  Broker broker(cfg, log.sink());
  std::optional<std::string> failure;
  std::vector<std::string> lines_at_failure;
  std::thread farm([&] {
    try {
      broker.run(job_of(kView + "s 0 0 0 1\n"), deadline(20));
    } catch (const std::exception& e) {  // FarmJobFailed, or the deadline's
      std::lock_guard<std::mutex> lock(log.mutex);
      lines_at_failure = log.lines;
      failure = e.what();
    }
  });
  zmq::context_t ctx(1);
  RawPeer peer(ctx, broker.endpoint());
  const JobSpec spec = peer.join("p", 1);
  // 60 in a few ms: more than the 20 a second shown, however the second falls.
  constexpr int kFetches = 60;
  for (int i = 0; i < kFetches; ++i) peer.send_message(FetchJob{spec.job + 1});
  peer.send_message(JobFailed{spec.job, FailureScope::job, "scene.nff:9: made up"});
  farm.join();
  REQUIRE(failure);
  CHECK(failure->find("failed on the workers: scene.nff:9: made up") != std::string::npos);
  int shown = 0, held_back = 0;
  for (const std::string& line : lines_at_failure) {
    shown += line.find("rejected fetch of job " + std::to_string(spec.job + 1)) != std::string::npos;
    int n = 0;
    if (std::sscanf(line.c_str(), "(%d more rejections not shown)", &n) == 1) held_back += n;
  }
  CHECK(shown < kFetches);
  CHECK(shown + held_back == kFetches);
}

TEST_CASE("job failure: a job announced early that a worker cannot load fails when it starts, not never") {
  // The service announces the next job while the current one finishes; a
  // worker that fails to load it reports job_failed for a job the broker is
  // not running yet. That report must count when the job starts, or the broker
  // would wait for a worker that will never load it.
  LogCapture log;
  Broker broker(test_broker_config(1), log.sink());
  ChildProcess worker = spawn_worker(broker.endpoint(), "w1");
  const FarmJob good = job_of(kView + "f 1 1 1 1 0 1 0 1\ns 0 0 0 1\n");
  const FarmJob bad = job_of(kView + "s 0 0\n");
  FarmHooks hooks;
  hooks.upcoming = [&] { return std::optional<FarmJob>(bad); };
  CHECK(broker.run(good, deadline(30), hooks).rgb == in_process(good));
  REQUIRE(log.count("announced early, while job") == 1);
  broker.serve_for(1.0);  // the worker's report on the early job arrives
  CHECK_THROWS_WITH_AS(broker.run(bad, deadline(30)),
                       doctest::Contains("failed on the workers: scene.nff:9: expected 4 numbers after 's'"),
                       FarmJobFailed);
  CHECK(worker.running());
  CHECK(broker.run(good, deadline(30)).rgb == in_process(good));  // and serves the next
}

TEST_CASE("job failure: a task whose result could never be sent fails the job, naming its size, before a pixel is rendered") {
  // A task of 342 rows 65536 wide makes a result of 257 MiB, more than a
  // result frame carries (no broker sends one: at most max_task_rows rows).
  // The worker allocated and rendered it all (gigabytes and minutes for a
  // taller one) for a result the broker would drop, or failed on a bare
  // "std::bad_alloc" as if the machine were at fault.
  HandBroker broker;
  ThreadWorker worker(thread_worker_config(broker.endpoint, "w1"));
  FarmJob wide = job_of(kView + "f 1 1 1 1 0 1 0 1\ns 0 0 0 1\n");
  wide.settings.width = 65536;
  wide.settings.height = 512;
  wide.settings.spp = 1;
  broker.welcome_with(wide, 5);
  broker.send_message(TaskAssign{5, 1, 1, 0, 342, 0, 65536});
  const auto failed = broker.wait_for<JobFailed>(5);
  REQUIRE(failed);
  CHECK(failed->job == 5);
  CHECK(failed->scope == FailureScope::job);
  CHECK(failed->reason ==
        "task 1: rows [0, 342) of pixels [0, 65536) make a result of 257 MiB, more than the 256 MiB a result frame "
        "may carry");
  // The worker serves on: the next job renders.
  const FarmJob small = job_of(kView + "f 1 1 1 1 0 1 0 1\ns 0 0 0 1\n");
  broker.send_message(JobSpec{6, fnv1a64(small.scene_text), small.scene_name, small.settings, small.scene_text});
  REQUIRE(broker.wait_for<JobReady>(10));
  broker.send_message(TaskAssign{6, 2, 1, 0, 16, 0, 16});
  const auto result = broker.wait_for<TaskResult>(10);
  REQUIRE(result);
  CHECK(result->rgb == in_process(small));
}

TEST_CASE("job failure: a failure of a scene with a 4096-byte name is reported in a reason the broker takes") {
  // The parse error starts with the scene's name: its 4100 bytes and more
  // made a `job_failed` the broker refused as malformed, so the job never
  // failed while the worker had dropped it.
  HandBroker broker;
  ThreadWorker worker(thread_worker_config(broker.endpoint, "w1"));
  REQUIRE(broker.wait_for<Ready>(5));
  broker.send_message(Welcome{100, 5, 1, 0});
  std::string name;
  while (name.size() < kMaxReasonBytes) name += "\xc3\xa9";  // é: a cut must not split one
  const std::string scene = kView + "s 0 0\n";
  broker.send_message(JobSpec{7, fnv1a64(scene), name, job_of(scene).settings, scene});
  const auto failed = broker.wait_for<JobFailed>(5);  // the broker's decoder: it threw on the reason's length
  REQUIRE(failed);
  CHECK(failed->reason.size() <= kMaxReasonBytes);
  CHECK(failed->reason.rfind(name.substr(0, 1024) + " [...] ", 0) == 0);
  CHECK(failed->reason.find(":9: expected 4 numbers after 's'") != std::string::npos);
}

TEST_CASE("job failure: a parse error quoting a scene's bytes that are not UTF-8 is reported, with U+FFFD for them") {
  // The error quotes the token as written (its printer escapes it): a Latin-1
  // byte in it is no text a `job_failed` can carry.
  HandBroker broker;
  ThreadWorker worker(thread_worker_config(broker.endpoint, "w1"));
  REQUIRE(broker.wait_for<Ready>(5));
  broker.send_message(Welcome{100, 5, 1, 0});
  const std::string scene = kView + "sc\xe8ne\x1b 1\n";
  broker.send_message(JobSpec{7, fnv1a64(scene), "latin1.nff", job_of(scene).settings, scene});
  const auto failed = broker.wait_for<JobFailed>(5);
  REQUIRE(failed);
  CHECK(failed->reason.find("unknown keyword \"sc\xef\xbf\xbdne\x1b\"") != std::string::npos);
}
