// ProgressMeter's line: rate and ETA from the rows rendered in this run, so a
// job resumed after a broker restart does not claim its journaled rows
// arrived in no time.
#include <doctest/doctest.h>

#include "broker/progress.h"

using namespace rayfarm;

TEST_CASE("progress line: rate and ETA of a fresh job") {
  const ProgressMeter meter(false, 5);
  CHECK(meter.line(100, 1000, 2, 4.0) == "rows 100/1000 (10%), 25.0 rows/s, ETA 36.0s, 2 worker(s)");
  CHECK(meter.line(0, 1000, 2, 4.0) == "rows 0/1000 (0%), 0.0 rows/s, ETA ?, 2 worker(s)");
}

TEST_CASE("progress line: rows resumed from the journal count as done, not in the rate") {
  const ProgressMeter meter(false, 5);
  // Right after the restart: 274 rows journaled, none rendered yet.
  CHECK(meter.line(274, 1024, 1, 0.05, 274) == "rows 274/1024 (27%), 0.0 rows/s, ETA ?, 1 worker(s)");
  // 50 more in 2 s: 25 rows/s for the 700 left.
  CHECK(meter.line(324, 1024, 1, 2.0, 274) == "rows 324/1024 (32%), 25.0 rows/s, ETA 28.0s, 1 worker(s)");
}
