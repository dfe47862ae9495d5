// What the broker does with results it cannot use: duplicates, stale and
// unassigned attempts, rows that do not match their task, frames that fail
// decoding for their content, and a worker that sends only such results or
// none at all. Raw peers (tests/farm_peers.h) play the bad workers beside
// real ones, on tcp://127.0.0.1 ephemeral ports; each image is compared byte
// for byte with the in-process render.
#include <doctest/doctest.h>

#include <limits>
#include <optional>
#include <string>

#include "broker/broker.h"
#include "tests/farm_peers.h"
#include "worker/worker.h"

using namespace rayfarm;
using namespace rayfarm::protocol;
using namespace rayfarm::test;

namespace {

// A broker on its own thread with one raw peer, whose workers are lost only
// after 10 s (liveness 100): the peer answers as slowly as a test needs.
// `ordered` as ordered_broker_config() takes it; the job runs for at most
// `deadline_s`.
struct PatientBroker {
  FarmJob job = small_job(32, 16, 1);
  LogCapture log;
  Broker broker;
  zmq::context_t ctx;
  RawPeer raw;
  BrokerThread run;
  PatientBroker(int ordered, double deadline_s)
      : broker(patient(ordered_broker_config(ordered)), log.sink()),
        raw(ctx, broker.endpoint()),
        run(broker, job, deadline_s) {}
  static BrokerConfig patient(BrokerConfig cfg) {
    cfg.liveness = 100;
    return cfg;
  }
};

}  // namespace

TEST_CASE("farm: duplicate, stale and unassigned results are dropped and only the first result counts") {
  const FarmJob job = small_job(32, 8, 1);
  const Scene scene = parse_nff(job.scene_text, job.scene_name);
  Renderer renderer(scene, job.settings);
  LogCapture log;
  Broker broker(ordered_broker_config(1), log.sink());
  zmq::context_t ctx;
  RawPeer a(ctx, broker.endpoint());
  BrokerThread run(broker, job, 30);

  a.join("A", 1);
  auto task_a = a.wait_for<TaskAssign>(5);
  REQUIRE(task_a);
  CHECK(task_a->attempt == 1);
  a.alive = false;  // A goes silent: after 5 x 100 ms the broker requeues its task

  RawPeer b(ctx, broker.endpoint());
  b.join("B", 1);
  auto task_b = b.wait_for<TaskAssign>(5);
  REQUIRE(task_b);
  CHECK(task_b->task != task_a->task);
  b.idle(0.9);
  const TaskResult result_b = render_task(renderer, *task_b);
  b.send_message(result_b);
  auto reissued = b.wait_for<TaskAssign>(5);  // A's task, attempt 2
  REQUIRE(reissued);
  CHECK(reissued->task == task_a->task);
  CHECK(reissued->attempt == 2);
  b.send_message(result_b);  // again: duplicate

  // A comes back: a new registration. Its old result is stale; a result for
  // the attempt it never held is unassigned.
  a.alive = true;
  a.send_message(Ready{"A", 21.0, 1, 1, 100, 1.0});
  REQUIRE(a.wait_for<Welcome>(5));
  const TaskResult stale = render_task(renderer, *task_a);
  a.send_message(stale);
  TaskResult not_yours = render_task(renderer, *reissued);
  a.send_message(not_yours);
  a.idle(0.2);                // (two sockets: give A's messages time to arrive first)
  b.send_message(not_yours);  // B holds attempt 2: accepted
  b.idle(0.3);

  // A real worker finishes the job.
  ThreadWorker real(thread_worker_config(broker.endpoint(), "real"));
  run.join();
  REQUIRE(run.error.empty());
  const nlohmann::json& rec = run.result.record;
  CHECK(rec["rejected"]["duplicate"] == 1);
  CHECK(rec["rejected"]["stale"] == 1);
  CHECK(rec["rejected"]["unassigned"] == 1);
  const auto& t = rec["tasks"][task_a->task];
  REQUIRE(t["attempts"].size() == 2);
  CHECK(t["attempts"][0]["worker"] == "A");
  CHECK(t["attempts"][0]["outcome"] == "lost");
  CHECK(t["worker"] == "B");
  CHECK(identical(run.result.rgb, in_process(job)));
  CHECK(log.count("dropped") + log.count("rejected") >= 3);
}

TEST_CASE("farm: a worker that heartbeats but never returns its tasks cannot stall the job: backups finish them") {
  // It claims a million SSCs of speed, takes tasks and keeps heartbeating, so
  // the broker never loses it; a real worker backs its tasks up once it is idle.
  const FarmJob job = small_job(64, 64, 4);
  Broker broker(test_broker_config(1), [](const std::string&) {});
  zmq::context_t ctx;
  RawPeer hog(ctx, broker.endpoint());
  BrokerThread run(broker, job, 60);
  hog.join("hog", 2, 1e6);
  auto held = hog.wait_for<TaskAssign>(5);
  REQUIRE(held);
  ThreadWorker real(thread_worker_config(broker.endpoint(), "real"));
  for (int i = 0; i < 600 && !run.finished; ++i) hog.idle(0.05);  // heartbeats, never a result
  run.join();
  REQUIRE(run.error.empty());
  const nlohmann::json& rec = run.result.record;
  CHECK(identical(run.result.rgb, in_process(job)));
  CHECK(rec["backups"].get<int>() >= 1);
  CHECK(worker_entry(rec, "hog")["rows"] == 0);
  CHECK(worker_entry(rec, "hog")["state"] == "active");  // never timed out: the backups did it
  CHECK(worker_entry(rec, "real")["rows"] == 64);
  const auto& t = rec["tasks"][held->task];
  CHECK(t["worker"] == "real");
  CHECK(t["attempts"][0]["outcome"] == "beaten");
  CHECK(t["attempts"][1]["backup"] == true);
  // No result was lost: no row counts as rendered again, the backups apart.
  CHECK(rec["tasks_reissued"] == 0);
  CHECK(rec["rows_reissued"] == 0);
  CHECK(rec["tasks_backed_up"].get<int>() >= 1);
  CHECK(rec["rows_backed_up"].get<int>() >= t["rows"].get<int>());
}

TEST_CASE("farm: a result whose rows do not match its task frees the worker and requeues the task at once") {
  // Weighted tasks, no backups: only the mismatch verdict itself can put the
  // task back before the worker would be lost.
  PatientBroker farm(1, 20);
  auto& [job, log, broker, ctx, raw, run] = farm;
  raw.join("raw", 1);
  auto task = raw.wait_for<TaskAssign>(5);
  REQUIRE(task);
  TaskResult wrong = result_for(*task, job.settings.width);
  const int rows = task->y1 - task->y0;
  wrong.y0 = task->y0 == 0 ? task->y1 : 0;  // the same number of rows, elsewhere
  wrong.y1 = wrong.y0 + rows;
  wrong.rgb.assign(static_cast<size_t>(rows) * job.settings.width * 3, 1.0f);
  raw.send_message(wrong);
  // Its credit is free again and the task is back at the head of the queue:
  // the next task it gets is the same one, second attempt.
  auto again = raw.wait_for<TaskAssign>(5);
  REQUIRE(again);
  CHECK(again->task == task->task);
  CHECK(again->attempt == 2);
  raw.send_message(Bye{});
  ThreadWorker real(thread_worker_config(broker.endpoint(), "real"));
  run.join();
  REQUIRE(run.error.empty());
  CHECK(identical(run.result.rgb, in_process(job)));
  CHECK(run.result.record["rejected"]["mismatch"] == 1);
  const auto& t = run.result.record["tasks"][task->task];
  CHECK(t["attempts"][0]["outcome"] == "lost");
  CHECK(t["worker"] == "real");
}

TEST_CASE("farm: a result that fails decoding for its pixels or length frees the worker and requeues its task at once") {
  // A worker with a broken FPU or bad memory that still heartbeats: its NaN
  // result was only counted as malformed, the task stayed held at it with its
  // credit, and with no backups (weighted tasks) the job never finished.
  PatientBroker farm(1, 20);
  auto& [job, log, broker, ctx, raw, run] = farm;
  raw.join("nan", 1);
  const auto task = raw.wait_for<TaskAssign>(5);
  REQUIRE(task);
  auto filled = [&](const TaskAssign& t) {
    TaskResult r = result_for(t, job.settings.width);
    r.rgb.assign(static_cast<size_t>(t.y1 - t.y0) * (t.x1 - t.x0) * 3, 0.5f);
    r.rgb[4] = std::numeric_limits<float>::quiet_NaN();
    return r;
  };
  raw.send_message(filled(*task));
  // Its credit is free again and the task back at the head of the queue: the
  // next task it gets is the same one, second attempt.
  const auto again = raw.wait_for<TaskAssign>(5);
  REQUIRE(again);
  CHECK(again->task == task->task);
  CHECK(again->attempt == 2);
  // A frame one pixel short is the same: the third attempt follows.
  Frames short_frame = encode(Message{filled(*again)});
  short_frame[0].resize(short_frame[0].size() - 12);
  raw.send_frames(short_frame);
  const auto third = raw.wait_for<TaskAssign>(5);
  REQUIRE(third);
  CHECK(third->task == task->task);
  CHECK(third->attempt == 3);
  // A bad result for an attempt it no longer holds is dropped as malformed:
  // attempt 3 stays live at it.
  raw.send_message(filled(*task));
  CHECK_FALSE(raw.wait_for<TaskAssign>(0.5));
  raw.send_message(Bye{});
  ThreadWorker real(thread_worker_config(broker.endpoint(), "real"));
  run.join();
  REQUIRE(run.error.empty());
  CHECK(identical(run.result.rgb, in_process(job)));
  const nlohmann::json& rec = run.result.record;
  CHECK(rec["rejected"]["corrupt"] == 2);
  CHECK(rec["rejected"]["malformed"] == 1);
  const auto& t = rec["tasks"][task->task];
  REQUIRE(t["attempts"].size() == 4);
  for (int a = 0; a < 3; ++a) CHECK(t["attempts"][a]["outcome"] == "lost");
  CHECK(t["worker"] == "real");
  CHECK(log.count("rejected message from nan#1: result of task " + std::to_string(task->task) +
                  " attempt 1 (job ") == 2);  // requeued once, then dropped
  CHECK(log.count("non-finite pixel value at x 1 of row " + std::to_string(task->y0) + "; task " +
                  std::to_string(task->task) + " requeued") == 1);
  CHECK(log.count("; task " + std::to_string(task->task) + " requeued") == 2);
}

TEST_CASE("farm: a worker whose results cannot be used is given no more of the job after three") {
  // Each corrupt or mismatched result puts its task back at the head of the
  // queue, and a broken worker that was the one with free credit got it
  // straight back: thousands of attempts a second and a growing job record.
  PatientBroker farm(1, 20);
  auto& [job, log, broker, ctx, raw, run] = farm;
  const JobSpec spec = raw.join("broken", 1);
  std::optional<TaskAssign> task = raw.wait_for<TaskAssign>(5);
  REQUIRE(task);
  const uint32_t first_task = task->task;
  for (int attempt = 1; attempt <= 3; ++attempt) {
    REQUIRE(task);
    CHECK(task->task == first_task);
    CHECK(task->attempt == attempt);
    TaskResult r = result_for(*task, job.settings.width);
    r.rgb.assign(static_cast<size_t>(task->y1 - task->y0) * (task->x1 - task->x0) * 3, 0.5f);
    if (attempt == 2) {  // a mismatch counts as a corrupt result does
      const int rows = task->y1 - task->y0;
      r.y0 = task->y0 == 0 ? task->y1 : 0;
      r.y1 = r.y0 + rows;
    } else {
      r.rgb[0] = std::numeric_limits<float>::infinity();
    }
    raw.send_message(r);
    task = raw.wait_for<TaskAssign>(attempt < 3 ? 5 : 0.5);
  }
  CHECK_FALSE(task);  // the third was its last
  // Loaded again, it is still left out of this job.
  raw.send_message(JobReady{spec.job, 0.0});
  CHECK_FALSE(raw.wait_for<TaskAssign>(0.5));
  ThreadWorker real(thread_worker_config(broker.endpoint(), "real"));
  run.join();
  REQUIRE(run.error.empty());
  CHECK(identical(run.result.rgb, in_process(job)));
  const nlohmann::json& rec = run.result.record;
  CHECK(rec["rejected"]["corrupt"] == 2);
  CHECK(rec["rejected"]["mismatch"] == 1);
  CHECK(rec["tasks"][first_task]["attempts"].size() == 4);
  CHECK(rec["tasks"][first_task]["worker"] == "real");
  bool excluded = false;
  for (const auto& w : rec["workers"]) excluded |= w["name"] == "broken" && w["state"] == "excluded";
  CHECK(excluded);
  CHECK(log.count("worker broken#1 sent 3 results of job ") == 1);
  CHECK(log.count("that could not be used (the last: result of task " + std::to_string(first_task) + " attempt 3 (job ") ==
        1);
  CHECK(log.count("): it is given no more of its tasks") == 1);
}

TEST_CASE("farm: a result rejected for its pixels or its length is logged with its task, job and rows") {
  // The line named the worker only ("result: non-finite pixel value"): which
  // task, and so which rows, it was for was left to guess.
  PatientBroker farm(0, 30);
  auto& [job, log, broker, ctx, raw, run] = farm;
  const JobSpec spec = raw.join("bad", 2);
  const auto first = raw.wait_for<TaskAssign>(5), second = raw.wait_for<TaskAssign>(5);
  REQUIRE(first);
  REQUIRE(second);
  auto filled = [&](const TaskAssign& t) {
    TaskResult r = result_for(t, job.settings.width);
    r.rgb.assign(static_cast<size_t>(t.y1 - t.y0) * (t.x1 - t.x0) * 3, 0.5f);
    return r;
  };
  TaskResult nan = filled(*first);
  nan.rgb[4] = std::numeric_limits<float>::quiet_NaN();  // the second pixel's green
  raw.send_message(nan);
  Frames short_frame = encode(Message{filled(*second)});
  short_frame[0].resize(short_frame[0].size() - 12);  // one pixel short
  raw.send_frames(short_frame);
  raw.send_message(Bye{});
  ThreadWorker real(thread_worker_config(broker.endpoint(), "real"));
  run.join();
  REQUIRE(run.error.empty());
  CHECK(identical(run.result.rgb, in_process(job)));
  auto named = [&](const TaskAssign& t) {
    return "rejected message from bad#1: result of task " + std::to_string(t.task) + " attempt 1 (job " +
           std::to_string(spec.job) + ", rows [" + std::to_string(t.y0) + ", " + std::to_string(t.y1) + ")): ";
  };
  CHECK(log.count(named(*first) + "non-finite pixel value at x 1 of row " + std::to_string(first->y0)) == 1);
  CHECK(log.count(named(*second) + "frame is ") == 1);
}
