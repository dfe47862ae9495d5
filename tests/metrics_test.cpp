// /metrics formatter (status/metrics.h): the exact exposition text, cumulative
// histogram buckets, label escaping, and every line in the format's grammar.
#include <doctest/doctest.h>

#include <regex>
#include <sstream>
#include <string>

#include "status/metrics.h"

using namespace rayfarm;

TEST_CASE("metrics: histogram buckets are upper bounds, counted once each") {
  Histogram h({0.1, 1});
  h.observe(0.05);
  h.observe(0.1);  // on the bound: le="0.1" includes it
  h.observe(0.5);
  h.observe(7);
  CHECK(h.counts == std::vector<uint64_t>{2, 1, 1});
  CHECK(h.count == 4);
  CHECK(h.sum == doctest::Approx(7.65));
}

TEST_CASE("metrics: the exposition text, byte for byte") {
  FarmMetrics m;
  m.jobs_by_state = {{"done", 2}, {"queued", 1}, {"running", 1}};
  m.rows_done = 1536;
  m.rows_per_second = 12.5;
  m.workers_by_state = {{"idle", 0}, {"rendering", 3}};
  m.rejected_by_reason = {{"stale", 4}};
  m.task_round_trip = Histogram({0.5, 2, 10});
  m.task_round_trip.observe(0.25);
  m.task_round_trip.observe(1);
  m.task_round_trip.observe(3);
  const std::string text = format_metrics(m);
  CHECK(text.find("# TYPE rayfarm_jobs gauge\nrayfarm_jobs{state=\"done\"} 2\nrayfarm_jobs{state=\"queued\"} 1\n") !=
        std::string::npos);
  CHECK(text.find("\nrayfarm_rows_done_total 1536\n") != std::string::npos);
  CHECK(text.find("\nrayfarm_rows_per_second 12.5\n") != std::string::npos);
  CHECK(text.find("\nrayfarm_workers{state=\"rendering\"} 3\n") != std::string::npos);
  CHECK(text.find("\nrayfarm_rejected_messages_total{reason=\"stale\"} 4\n") != std::string::npos);
  CHECK(text.find("# TYPE rayfarm_task_round_trip_seconds histogram\n"
                  "rayfarm_task_round_trip_seconds_bucket{le=\"0.5\"} 1\n"
                  "rayfarm_task_round_trip_seconds_bucket{le=\"2\"} 2\n"
                  "rayfarm_task_round_trip_seconds_bucket{le=\"10\"} 3\n"
                  "rayfarm_task_round_trip_seconds_bucket{le=\"+Inf\"} 3\n"
                  "rayfarm_task_round_trip_seconds_sum 4.25\n"
                  "rayfarm_task_round_trip_seconds_count 3\n") != std::string::npos);
}

TEST_CASE("metrics: label values are escaped, every line parses") {
  FarmMetrics m;
  m.rejected_by_reason = {{"bad \"frame\"\\\nx", 1}};
  const std::string text = format_metrics(m);
  CHECK(text.find(R"(rayfarm_rejected_messages_total{reason="bad \"frame\"\\\nx"} 1)") != std::string::npos);
  // The text format's grammar: comments, or name{labels} value.
  const std::regex comment(R"(# (HELP|TYPE) [a-zA-Z_:][a-zA-Z0-9_:]* .+)");
  const std::regex sample(R"([a-zA-Z_:][a-zA-Z0-9_:]*(\{[a-zA-Z_][a-zA-Z0-9_]*="([^"\\\n]|\\[\\"n])*"\})? ([-+]?[0-9.eE+-]+|\+Inf|NaN))");
  std::istringstream lines(text);
  std::string line;
  int count = 0;
  while (std::getline(lines, line)) {
    CAPTURE(line);
    CHECK((std::regex_match(line, comment) || std::regex_match(line, sample)));
    ++count;
  }
  CHECK(count > 10);
  CHECK(text.back() == '\n');
}
