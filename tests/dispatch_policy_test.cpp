// DispatchPolicy tests: the pure decisions shared by the broker and the
// replay, driven by hand with explicit times (no sockets, no clocks).
#include <doctest/doctest.h>

#include <map>
#include <set>

#include "broker/dispatch_policy.h"
#include "tracer/error.h"

using namespace rayfarm;

namespace {

std::vector<Dispatch> dispatch_at(DispatchPolicy& p, double now) {
  std::vector<Dispatch> out;
  p.dispatch(now, out);
  return out;
}

// Registers two workers (serials 1 and 2) of these weights, both ready at t = 0.
void two_ready(DispatchPolicy& p, double weight1 = 21, double weight2 = 21, int credit = 1) {
  p.add_worker(1, "w1", weight1, credit);
  p.add_worker(2, "w2", weight2, credit);
  p.worker_ready(1, 0);
  p.worker_ready(2, 0);
}

void finish(DispatchPolicy& p, const Dispatch& d, double now, double busy) {
  CHECK(p.on_result(d.worker, d.task, d.attempt, {d.y0, d.y1, d.x0, d.x1}, now, busy, 0) == Verdict::accepted);
}

}  // namespace

TEST_CASE("dispatch: policy names parse, and a wrong one lists the known ones") {
  CHECK(parse_policy("paper", "x") == PolicyKind::paper);
  CHECK(parse_policy("adaptive", "x") == PolicyKind::adaptive);
  try {
    parse_policy("fastest", "--policy");
    FAIL("no error");
  } catch (const InputError& e) {
    CHECK(std::string(e.what()) == "--policy: unknown dispatch policy \"fastest\" (expected one of: paper, weighted, adaptive)");
  }
}

TEST_CASE("dispatch: paper policy gives constant rows top to bottom, one task in flight, first N tasks to N workers") {
  TaskBoard board(10);
  PolicyOptions o;
  o.kind = PolicyKind::paper;
  o.base_task_rows = 2;
  DispatchPolicy p(o, board);
  for (uint32_t w = 1; w <= 3; ++w) p.add_worker(w, "w" + std::to_string(w), w == 3 ? 60.3 : 21.0, 4);
  for (uint32_t w = 1; w <= 3; ++w) p.worker_ready(w, 0);
  const auto first = dispatch_at(p, 0);
  REQUIRE(first.size() == 3);  // credit 4 announced, one at a time taken
  for (size_t i = 0; i < 3; ++i) {
    CHECK(first[i].worker == i + 1);
    CHECK(first[i].y0 == int(2 * i));
    CHECK(first[i].y1 - first[i].y0 == 2);  // the R4000 too: constant size
  }
  CHECK(dispatch_at(p, 0).empty());
  finish(p, first[1], 1, 1);
  const auto next = dispatch_at(p, 1);
  REQUIRE(next.size() == 1);
  CHECK(next[0].worker == 2);  // who returned a result gets the next task
  CHECK(next[0].y0 == 6);
}

TEST_CASE("dispatch: weighted policy sizes by declared weight (the paper's 4.4.2)") {
  TaskBoard board(100);
  PolicyOptions o;
  o.kind = PolicyKind::weighted;
  o.base_task_rows = 4;
  DispatchPolicy p(o, board);
  two_ready(p, 17.9, 60.3);
  const auto d = dispatch_at(p, 0);
  REQUIRE(d.size() == 2);
  CHECK(d[0].y1 - d[0].y0 == 3);
  CHECK(d[1].y1 - d[1].y0 == 11);
  CHECK(nominal_task_rows(o, 60.3) == 11);
}

TEST_CASE("dispatch: adaptive samples the image first, then every 16th row, then the dearest rows, in shrinking tasks") {
  const int h = 64;
  TaskBoard board(h);
  DispatchPolicy p(PolicyOptions{}, board);
  two_ready(p);
  auto wave = dispatch_at(p, 0);
  REQUIRE(wave.size() == 2);
  CHECK(wave[0].y0 == 0);   // stride order: 0, 32, 16, 48, ...
  CHECK(wave[1].y0 == 32);
  CHECK(wave[0].y1 - wave[0].y0 == 1);  // single rows until about one row per worker is measured
  // Rows near the top are ten times dearer than the rest.
  auto cost = [](int y) { return y < 16 ? 10.0 : 1.0; };
  double now = 0;
  std::vector<double> task_costs;
  std::vector<std::pair<int, int>> tasks;
  std::set<int> rows_seen;
  while (!board.complete()) {
    std::vector<Dispatch> next;
    for (const Dispatch& d : wave) {
      double c = 0;
      for (int y = d.y0; y < d.y1; ++y) c += cost(y), rows_seen.insert(y);
      task_costs.push_back(c);
      tasks.emplace_back(d.y0, d.y1);
      now += c / 2;
      finish(p, d, now, c);
    }
    wave = dispatch_at(p, now);
    if (wave.empty()) break;
  }
  CHECK(board.complete());
  CHECK(rows_seen.size() == size_t(h));
  CHECK(p.backups() == 0);
  // The rest of the 16-row grid goes out alone (the preview covers the frame),
  // then the next task is in the dear band, and the last ones are small.
  REQUIRE(tasks.size() > 4);
  CHECK(tasks[2] == std::make_pair(16, 17));
  CHECK(tasks[3] == std::make_pair(48, 49));
  CHECK(task_costs[4] >= 10);
  CHECK(task_costs.back() <= 2);
  CHECK(p.row_costs()[3] == doctest::Approx(10));
}

TEST_CASE("dispatch: adaptive backs up a straggler on an idle worker, the first result wins, the loser frees its credit") {
  TaskBoard board(4);
  PolicyOptions o;
  o.prior_costs = {1, 1, 1, 1};  // seconds per row: known from a previous frame
  DispatchPolicy p(o, board);
  two_ready(p);
  auto d = dispatch_at(p, 0);
  REQUIRE(d.size() == 2);
  const Dispatch stuck = d[1];
  double now = 0;
  Dispatch last = d[0];
  while (!last.backup) {  // the fast worker renders everything else at 1 s a row
    now += last.y1 - last.y0;
    finish(p, last, now, last.y1 - last.y0);
    const auto more = dispatch_at(p, now);
    REQUIRE(more.size() == 1);
    last = more[0];
  }
  // Rows ran out at t = 3, when the stuck row (expected at t = 1) was overdue beyond doubt.
  CHECK(now == 3);
  CHECK(last.task == stuck.task);
  CHECK(last.attempt == 2);
  finish(p, last, now + 1, 1);
  CHECK(board.complete());
  CHECK(p.backups() == 1);
  CHECK(p.on_result(2, stuck.task, stuck.attempt, {stuck.y0, stuck.y1, stuck.x0, stuck.x1}, now + 1, 5, 0) == Verdict::beaten);
  CHECK(board.task(stuck.task).attempts[0].outcome == std::string("beaten"));
}

TEST_CASE("dispatch: a removed worker's tasks are requeued and go out first, with the next attempt") {
  TaskBoard board(8);
  PolicyOptions o;
  o.kind = PolicyKind::paper;
  DispatchPolicy p(o, board);
  two_ready(p);
  const auto d = dispatch_at(p, 0);
  REQUIRE(d.size() == 2);
  CHECK(p.remove_worker(1, 1) == 1);
  finish(p, d[1], 2, 1);
  const auto again = dispatch_at(p, 2);
  REQUIRE(again.size() == 1);
  CHECK(again[0].task == d[0].task);
  CHECK(again[0].attempt == 2);
  CHECK(p.on_result(1, d[0].task, 1, {d[0].y0, d[0].y1, d[0].x0, d[0].x1}, 3, 1, 0) == Verdict::stale);
}

TEST_CASE("dispatch: adaptive learns a worker's speed when it differs from the declared weight") {
  TaskBoard board(400);
  PolicyOptions o;
  o.prior_costs.assign(400, 1.0);
  DispatchPolicy p(o, board);
  two_ready(p);  // worker 2 declares an SSC but renders 4x slower
  double now = 0;
  for (int round = 0; round < 8; ++round) {
    for (const Dispatch& d : dispatch_at(p, now)) {
      const double rows = d.y1 - d.y0;
      finish(p, d, now + 1, d.worker == 2 ? 4 * rows : rows);
    }
    now += 1;
  }
  CHECK(p.speed_of(1) == doctest::Approx(1.0));
  CHECK(p.speed_of(2) == doctest::Approx(0.25));
}

// Runs a job to the end on workers of these speeds (credit 1) with every row
// costing `row_cost` s on a speed-1 worker and a span its pixels' share;
// returns the tasks in dispatch order.
static std::vector<Dispatch> run_uniform(TaskBoard& board, DispatchPolicy& p, const std::vector<double>& speeds,
                                         double row_cost = 1.0) {
  std::multimap<double, Dispatch> running;  // by finish time
  std::vector<Dispatch> all;
  for (size_t i = 0; i < speeds.size(); ++i) {
    p.add_worker(static_cast<uint32_t>(i + 1), "w" + std::to_string(i + 1), 21.0 * speeds[i], 1);
    p.worker_ready(static_cast<uint32_t>(i + 1), 0);
  }
  double now = 0;
  for (;;) {
    for (const Dispatch& d : dispatch_at(p, now)) {
      const double busy = row_cost * (d.y1 - d.y0) * double(d.x1 - d.x0) / board.width() / speeds[d.worker - 1];
      running.emplace(now + busy, d);
      all.push_back(d);
    }
    if (running.empty()) break;
    const auto next = running.begin();
    now = next->first;
    const Dispatch d = next->second;
    running.erase(next);
    const double busy = row_cost * (d.y1 - d.y0) * double(d.x1 - d.x0) / board.width() / speeds[d.worker - 1];
    p.on_result(d.worker, d.task, d.attempt, {d.y0, d.y1, d.x0, d.x1}, now, busy, 0);
  }
  return all;
}

TEST_CASE("dispatch: adaptive cuts only the last rows into pixel spans, left to right, each pixel once") {
  const int h = 48, width = 256;
  TaskBoard board(h, width);
  PolicyOptions o;
  o.prior_costs.assign(h, 1.0);
  DispatchPolicy p(o, board);
  // One fast worker and three slow ones: a whole row on a slow worker at the
  // end would take 4 s while the fast one idles. Rows cost 1.25 s, not the
  // 1 s the previous frame said.
  const std::vector<Dispatch> tasks = run_uniform(board, p, {4, 1, 1, 1}, 1.25);
  CHECK(board.complete());
  size_t first_span = tasks.size();  // index of the first span task
  std::map<int, int> next_x;  // row -> pixels covered so far, left to right
  int whole_rows = 0;
  for (size_t i = 0; i < tasks.size(); ++i) {
    const Dispatch& d = tasks[i];
    if (d.backup) continue;
    if (d.x0 == 0 && d.x1 == width) {
      whole_rows += d.y1 - d.y0;
      continue;
    }
    first_span = std::min(first_span, i);
    CHECK(d.y1 - d.y0 == 1);
    CHECK(d.x1 - d.x0 >= o.min_span_pixels);
    CHECK(d.x0 == next_x[d.y0]);  // spans of a row go out left to right, none twice
    next_x[d.y0] = d.x1;
  }
  for (const auto& [y, x] : next_x) CHECK(x == width);  // every split row covered
  REQUIRE(first_span < tasks.size());  // the tail was cut
  CHECK(whole_rows >= h / 2);          // ...and only the tail
  CHECK(whole_rows + static_cast<int>(next_x.size()) == h);
  // A row rendered in spans is measured too: the sum of its spans' costs.
  const std::vector<double> learned = p.row_costs();
  REQUIRE(learned.size() == size_t(h));
  for (const auto& [y, x] : next_x) CHECK(learned[static_cast<size_t>(y)] == doctest::Approx(1.25));

  // Spans off: the same job in whole rows.
  TaskBoard rows_only(h, width);
  o.min_span_pixels = 0;
  DispatchPolicy q(o, rows_only);
  for (const Dispatch& d : run_uniform(rows_only, q, {4, 1, 1, 1})) CHECK((d.x0 == 0 && d.x1 == width));
  CHECK(rows_only.complete());
}
