// StatusBoard (status/status_board.h): rows copied as they arrive, a new frame
// starts a fresh image, the worker table, metrics that keep counting across
// jobs, old images dropped.
#include <doctest/doctest.h>

#include <vector>

#include "status/preview.h"
#include "status/status_board.h"

using namespace rayfarm;

namespace {

// A turn of a 4x4 frame (broker job `frame`) in which `bands` arrived.
FarmProgress turn(uint64_t frame, const std::vector<float>& image, std::vector<std::pair<int, int>> bands,
                  int rows_done) {
  FarmProgress p;
  p.job = frame;
  p.width = 4;
  p.height = 4;
  p.rows_total = 4;
  p.rows_done = rows_done;
  p.image = &image;
  p.new_bands = std::move(bands);
  for (size_t i = 0; i < p.new_bands.size(); ++i) p.new_round_trips.push_back(0.2);
  WorkerView w;
  w.name = "w1";
  w.weight = 21;
  w.rows = rows_done;
  w.busy_s = 2;
  w.state = rows_done < 4 ? "rendering" : "idle";
  p.worker_views = {w};
  return p;
}

// Row y has the value y / 4 (+ offset) in every channel.
std::vector<float> row_valued_image(float offset = 0) {
  std::vector<float> rgb(4 * 4 * 3);
  for (size_t i = 0; i < rgb.size(); ++i) rgb[i] = static_cast<float>(i / 12) / 4.f + offset;
  return rgb;
}

}  // namespace

TEST_CASE("status board: workers and metrics as the broker reports them") {
  StatusBoard board;
  const std::vector<float> image = row_valued_image();
  board.update(turn(70, image, {{0, 1}}, 1), 7);
  const nlohmann::json workers = board.workers_json();
  REQUIRE(workers.size() == 1);
  CHECK(workers[0]["rows_per_s"] == doctest::Approx(0.5));  // 1 row in 2 busy seconds
  CHECK(workers[0]["state"] == "rendering");
  board.update(turn(70, image, {{2, 4}, {1, 2}}, 4), 7);
  const FarmMetrics m = board.metrics();
  CHECK(m.rows_done == 4);
  CHECK(m.task_round_trip.count == 3);
  CHECK(m.workers_by_state.at("idle") == 1);
  CHECK(m.workers_by_state.at("lost") == 0);
  CHECK(board.preview_png(7).has_value());
  CHECK_FALSE(board.preview_png(70).has_value());  // known by the API's id, not the broker's
}

TEST_CASE("status board: the preview holds only the rows reported, the next frame starts afresh") {
  StatusBoard board;
  std::vector<float> image = row_valued_image();
  board.update(turn(1, image, {{2, 3}}, 1), 5);
  image[0] = 1.0f;  // a row not reported yet must not leak into the preview
  CHECK(board.preview_png(5).value() == preview_png(4, 4, row_valued_image(), {false, false, true, false}));

  const std::vector<float> next_frame = row_valued_image(0.5f);
  board.update(turn(2, next_frame, {{0, 1}}, 1), 5);  // job 5's second frame: broker job 2
  CHECK(board.preview_png(5).value() == preview_png(4, 4, next_frame, {true, false, false, false}));
  CHECK(board.metrics().rows_done == 2);
}

TEST_CASE("status board: restored rows show in the preview but are not counted as done in this run") {
  StatusBoard board;
  const std::vector<float> image = row_valued_image();
  FarmProgress p = turn(3, image, {{0, 2}}, 2);
  p.rows_restored = 2;  // journaled before a restart: the first turn brings them as bands
  board.update(p, 9);
  CHECK(board.metrics().rows_done == 0);
  CHECK(board.preview_png(9).value() == preview_png(4, 4, image, {true, true, false, false}));
}

TEST_CASE("status board: rejections count across jobs, only the newest jobs keep images") {
  StatusBoard board(2);
  const std::vector<float> image = row_valued_image();
  for (uint64_t job = 1; job <= 3; ++job) {
    FarmProgress p = turn(job, image, {{0, 4}}, 4);
    p.rejected = {{"stale", 2}};  // the broker counts per job
    board.update(p);
    p.new_bands.clear();  // a later turn of the same job: no news, the same count
    p.new_round_trips.clear();
    board.update(p);
    FarmProgress idle;  // between jobs the broker still reports its last job's count
    idle.rejected = p.rejected;
    board.update(idle);
  }
  CHECK(board.metrics().rejected_by_reason.at("stale") == 6);
  CHECK(board.metrics().rows_done == 12);
  CHECK_FALSE(board.preview_png(1).has_value());
  CHECK(board.preview_png(2).has_value());
  CHECK(board.preview_png(3).has_value());
}

TEST_CASE("status board: between jobs the worker table keeps the last job's work") {
  StatusBoard board;
  const std::vector<float> image = row_valued_image();
  board.update(turn(1, image, {{0, 4}}, 4));
  FarmProgress idle;  // the broker between jobs: the same worker, no job numbers
  WorkerView w;
  w.name = "w1";
  w.state = "idle";
  idle.worker_views = {w};
  board.update(idle);
  board.update(idle);
  const nlohmann::json workers = board.workers_json();
  REQUIRE(workers.size() == 1);
  CHECK(workers[0]["rows_done"] == 4);
  CHECK(workers[0]["busy_s"] == 2.0);
}
