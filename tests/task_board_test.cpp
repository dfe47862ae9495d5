// TaskBoard for a resumed job: rows restored after a broker restart are never
// cut into tasks, count as done from the start, and a board whose every row
// was restored is complete; judge() decides as accept() does, changing nothing.
#include <doctest/doctest.h>

#include "broker/job_record.h"
#include "broker/task_board.h"

using namespace rayfarm;

TEST_CASE("task board: restored rows are skipped, counted done, and split the bands around them") {
  TaskBoard board(10, 1, {{2, 4}, {7, 8}, {3, 5}});  // overlapping bands count once
  CHECK(board.rows_restored() == 4);              // rows 2, 3, 4, 7
  CHECK(board.rows_done() == 4);
  CHECK(board.rows_waiting() == 6);
  // Copies: the board's records move as it grows.
  const TaskRecord a = *board.next(1, "w1", 4, 0);
  CHECK(a.y0 == 0);
  CHECK(a.y1 == 2);  // stops before restored row 2
  // Coarse to fine: band 4..8 starts on a restored row, so band 8..10 is next,
  // then the scraps from the top.
  const TaskRecord b = *board.next(1, "w1", 4, 0);
  CHECK(b.y0 == 8);
  CHECK(b.y1 == 10);
  const TaskRecord c = *board.next(2, "w2", 4, 0);
  CHECK(c.y0 == 5);
  CHECK(c.y1 == 7);  // stops before restored row 7
  CHECK(!board.next(2, "w2", 4, 0));
  CHECK(board.rows_waiting() == 0);
  for (const TaskRecord& t : {a, b}) CHECK(board.accept(1, t.id, 1, t.band(), 1, 0, 0) == Verdict::accepted);
  CHECK(!board.complete());
  CHECK(board.accept(2, c.id, 1, {5, 7, 0, 1}, 1, 0, 0) == Verdict::accepted);
  CHECK(board.complete());
  CHECK(board.rows_done() == 10);

  TaskBoard all(3, 1, {{0, 3}});
  CHECK(all.complete());
  CHECK(!all.next(1, "w1", 1, 0));
}

TEST_CASE("task board: judge gives accept's verdict without marking anything") {
  TaskBoard board(4);
  const TaskRecord* t = board.next(1, "w1", 2, 0);
  REQUIRE(t);
  const uint32_t id = t->id;
  CHECK(board.judge(2, id, 1, {0, 2, 0, 1}) == Verdict::unassigned);
  CHECK(board.judge(1, id, 1, {0, 3, 0, 1}) == Verdict::mismatch);
  CHECK(board.judge(1, id, 1, {0, 2, 0, 1}) == Verdict::accepted);
  CHECK(board.judge(1, id, 1, {0, 2, 0, 1}) == Verdict::accepted);  // still: judging changed nothing
  CHECK(board.rows_done() == 0);
  CHECK(board.rows_waiting() == 2);
  board.requeue(id, 1, 1);
  CHECK(board.rows_waiting() == 4);  // the lost rows wait again
  CHECK(board.judge(1, id, 1, {0, 2, 0, 1}) == Verdict::stale);
  CHECK(board.accept(1, id, 1, {0, 2, 0, 1}, 1, 0, 0) == Verdict::stale);
}

TEST_CASE("task board: holds names only an attempt live at that worker") {
  TaskBoard board(4);
  const uint32_t id = board.next(1, "w1", 2, 0)->id;
  CHECK(board.holds(1, id, 1));
  CHECK_FALSE(board.holds(2, id, 1));   // another worker's
  CHECK_FALSE(board.holds(1, id, 2));   // no such attempt
  CHECK_FALSE(board.holds(1, id, 0));
  CHECK_FALSE(board.holds(1, id + 1, 1));  // no such task
  board.requeue(id, 1, 1);
  CHECK_FALSE(board.holds(1, id, 1));  // lost
  REQUIRE(board.next(1, "w1", 2, 2)->id == id);
  CHECK(board.holds(1, id, 2));
  CHECK(board.accept(1, id, 2, {0, 2, 0, 1}, 3, 0, 0) == Verdict::accepted);
  CHECK_FALSE(board.holds(1, id, 2));  // done
}

TEST_CASE("task board: a row whose spans were lost waits again, counted once") {
  TaskBoard board(2, 10);
  const TaskRecord a = *board.cut_span(1, "a", 0, 0, 3, 0);
  const TaskRecord b = *board.cut_span(2, "b", 0, 3, 6, 0);
  board.cut_span(3, "c", 0, 6, 10, 0);
  board.cut(3, "c", 1, 2, 0);
  CHECK(board.rows_waiting() == 0);
  board.requeue(a.id, 1, 1);
  board.requeue(b.id, 2, 1);
  CHECK(board.rows_waiting() == 1);  // row 0, not two rows for its two lost spans
  REQUIRE(board.next(3, "c", 1, 2));  // hands out span a again
  CHECK(board.rows_waiting() == 1);  // span b still waits
  REQUIRE(board.next(3, "c", 1, 2));
  CHECK(board.rows_waiting() == 0);
  // A lost span of a row still being cut: the row is counted once.
  TaskBoard open_row(1, 10);
  const TaskRecord first = *open_row.cut_span(1, "a", 0, 0, 4, 0);
  CHECK(open_row.rows_waiting() == 1);
  open_row.requeue(first.id, 1, 1);
  CHECK(open_row.rows_waiting() == 1);
}

TEST_CASE("task board: a row cut into spans left to right is done when all its pixels are") {
  TaskBoard board(3, 10);
  const TaskRecord a = *board.cut_span(1, "a", 1, 0, 4, 0);
  CHECK(a.span);
  CHECK(a.pixels() == 4);
  CHECK(!board.is_fresh(1));
  REQUIRE(board.open_span());
  CHECK(*board.open_span() == std::make_pair(1, 4));
  CHECK(!board.all_handed_out());
  const TaskRecord b = *board.cut_span(2, "b", 1, 4, 10, 0);
  CHECK(!board.open_span());
  // A result must name the task's pixels; a whole-row claim is a mismatch.
  CHECK(board.judge(1, a.id, 1, {1, 2, 0, 10}) == Verdict::mismatch);
  CHECK(board.accept(2, b.id, 1, b.band(), 1, 0, 0) == Verdict::accepted);
  CHECK(board.pixels_done(1) == 6);
  CHECK(board.rows_done() == 0);  // not until the row's last span is in
  CHECK(board.accept(1, a.id, 1, a.band(), 2, 0, 0) == Verdict::accepted);
  CHECK(board.pixels_done(1) == 10);
  CHECK(board.rows_done() == 1);
  // Whole rows on the same board are whole-width tasks, not spans.
  const TaskRecord c = *board.cut(1, "a", 0, 1, 3);
  CHECK(!c.span);
  CHECK(c.band() == PixelBand{0, 1, 0, 10});
  CHECK(board.rows_waiting() == 1);
  const TaskRecord d = *board.cut_span(2, "b", 2, 0, 5, 3);
  CHECK(board.rows_waiting() == 1);  // row 2: its last span not yet handed out
  board.cut_span(2, "b", 2, 5, 10, 3);
  CHECK(board.rows_waiting() == 0);
  CHECK(board.all_handed_out());
  CHECK(board.accept(1, c.id, 1, c.band(), 4, 0, 0) == Verdict::accepted);
  CHECK(board.accept(2, d.id, 1, d.band(), 4, 0, 0) == Verdict::accepted);
  CHECK(board.rows_done() == 2);
  CHECK(!board.complete());
}

TEST_CASE("job record: rows re-issued are those rendered again after a loss, backups of stragglers counted apart") {
  TaskBoard board(12, 4);
  // A straggler backed up on another worker, whose copy wins: no row was lost.
  const TaskRecord slow = *board.cut(1, "w1", 0, 4, 0);
  CHECK(board.backup(slow.id, 2, "w2", 1).attempts.back().backup);
  CHECK(board.accept(2, slow.id, 2, slow.band(), 2, 0, 0) == Verdict::accepted);
  // A task whose worker is gone: handed out again, its rows rendered again.
  const TaskRecord lost = *board.cut(1, "w1", 4, 8, 3);
  board.requeue(lost.id, 1, 4);
  const TaskRecord again = *board.next(2, "w2", 4, 5);
  REQUIRE(again.id == lost.id);
  CHECK(board.accept(2, lost.id, 2, lost.band(), 6, 0, 0) == Verdict::accepted);
  // One lost (its result held other rows), then backed up when its second attempt straggles: both.
  const TaskRecord rest = *board.cut(2, "w2", 8, 12, 7);
  CHECK(board.accept(2, rest.id, 1, {rest.y0, rest.y1 - 1, 0, 4}, 8, 0, 0) == Verdict::mismatch);
  board.requeue(rest.id, 2, 8);
  const TaskRecord retried = *board.next(3, "w3", 4, 9);
  board.backup(retried.id, 2, "w2", 10);
  CHECK(board.accept(3, rest.id, 2, rest.band(), 11, 0, 0) == Verdict::accepted);
  REQUIRE(board.complete());

  JobRecordInput in;
  in.settings.width = 4;
  in.settings.height = 12;
  in.board = &board;
  const nlohmann::json r = make_job_record(in);
  CHECK(r["tasks_reissued"] == 2);
  CHECK(r["rows_reissued"] == 8);
  CHECK(r["pixels_reissued"] == 32);
  CHECK(r["tasks_backed_up"] == 2);
  CHECK(r["rows_backed_up"] == 8);
  CHECK(r["pixels_backed_up"] == 32);
}
