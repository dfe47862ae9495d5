// StatusBoard (status/status_board.h): rows copied as they arrive, the worker
// table, metrics that keep counting across jobs, old images dropped.
#include <doctest/doctest.h>

#include <vector>

#include "status/preview.h"
#include "status/status_board.h"

using namespace rayfarm;

namespace {

// A turn of a 4x4 job in which `bands` arrived; the image holds value = row / 4.
FarmProgress turn(uint64_t job, const std::vector<float>& image, std::vector<std::pair<int, int>> bands, int rows_done) {
  FarmProgress p;
  p.job = job;
  p.width = 4;
  p.height = 4;
  p.rows_total = 4;
  p.rows_done = rows_done;
  p.scene_name = "scenes/balls.nff";
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

std::vector<float> row_valued_image() {
  std::vector<float> rgb(4 * 4 * 3);
  for (size_t i = 0; i < rgb.size(); ++i) rgb[i] = static_cast<float>(i / 12) / 4.f;
  return rgb;
}

}  // namespace

TEST_CASE("status board: jobs, rows and workers as the broker reports them") {
  StatusBoard board;
  const std::vector<float> image = row_valued_image();
  board.update(turn(7, image, {{0, 1}}, 1));
  nlohmann::json jobs = board.jobs_json();
  REQUIRE(jobs.size() == 1);
  CHECK(jobs[0]["id"] == 7);
  CHECK(jobs[0]["state"] == "running");
  CHECK(jobs[0]["rows_done"] == 1);
  CHECK(jobs[0]["scene"] == "scenes/balls.nff");
  const nlohmann::json workers = board.workers_json();
  REQUIRE(workers.size() == 1);
  CHECK(workers[0]["rows_per_s"] == doctest::Approx(0.5));  // 1 row in 2 busy seconds
  CHECK(workers[0]["state"] == "rendering");

  board.update(turn(7, image, {{2, 4}, {1, 2}}, 4));
  CHECK(board.job_json(7).value()["state"] == "done");
  CHECK_FALSE(board.job_json(8).has_value());
  CHECK_FALSE(board.record(7).has_value());
  board.set_record(7, {{"total_s", 1.5}});
  CHECK(board.record(7).value()["total_s"] == 1.5);
  const FarmMetrics m = board.metrics();
  CHECK(m.rows_done == 4);
  CHECK(m.task_round_trip.count == 3);
  CHECK(m.workers_by_state.at("idle") == 1);
  CHECK(m.workers_by_state.at("lost") == 0);
  CHECK(board.jobs_by_state().at("done") == 1);
}

TEST_CASE("status board: the preview holds only the rows reported, filled from their neighbours") {
  StatusBoard board;
  std::vector<float> image = row_valued_image();
  board.update(turn(1, image, {{2, 3}}, 1));
  image[0] = 1.0f;  // a row not reported yet must not leak into the preview
  const std::string png = board.preview_png(1).value();
  const std::vector<bool> only_row_2{false, false, true, false};
  CHECK(png == preview_png(4, 4, row_valued_image(), only_row_2));
  CHECK_FALSE(board.preview_png(2).has_value());
}

TEST_CASE("status board: rejections count across jobs; only the newest jobs keep images") {
  StatusBoard board(2);
  const std::vector<float> image = row_valued_image();
  for (uint64_t job = 1; job <= 3; ++job) {
    FarmProgress p = turn(job, image, {{0, 4}}, 4);
    p.rejected = {{"stale", 2}};  // the broker counts per job
    board.update(p);
    p.new_bands.clear();  // a later turn of the same job: no news, the same count
    p.new_round_trips.clear();
    board.update(p);
  }
  CHECK(board.metrics().rejected_by_reason.at("stale") == 6);
  CHECK(board.metrics().rows_done == 12);
  CHECK_FALSE(board.preview_png(1).has_value());
  CHECK(board.preview_png(2).has_value());
  CHECK(board.preview_png(3).has_value());
  CHECK(board.jobs_json().size() == 3);
}
