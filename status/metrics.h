// /metrics: the farm's numbers in the Prometheus text exposition format
// (version 0.0.4), so a Prometheus server or any scraper can chart the farm
// without parsing the JSON API. A formatter over plain structs: whoever owns
// the numbers (the broker loop, the job service) fills FarmMetrics, this file
// only writes it. Histogram buckets follow Prometheus: cumulative, "le" bounds.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace rayfarm {

// A fixed-bucket histogram of seconds.
struct Histogram {
  std::vector<double> bounds;    // upper bounds, increasing; +Inf is implicit
  std::vector<uint64_t> counts;  // per bucket (not cumulative), bounds.size() + 1
  double sum = 0;
  uint64_t count = 0;

  explicit Histogram(std::vector<double> upper_bounds);
  void observe(double value);
};

// Task round-trip bounds: dispatch to result, 10 ms to 5 min.
std::vector<double> round_trip_bounds();

struct FarmMetrics {
  std::map<std::string, int> jobs_by_state;        // every state, zeros included
  uint64_t rows_done = 0;                          // accepted rows since start (a counter)
  double rows_per_second = 0;                      // over the last few seconds
  std::map<std::string, int> workers_by_state;     // loading, rendering, idle, lost
  std::map<std::string, uint64_t> rejected_by_reason;  // dropped messages since start
  Histogram task_round_trip{round_trip_bounds()};  // seconds
};

// The exposition text: HELP and TYPE lines, one sample per line, "\n" endings.
std::string format_metrics(const FarmMetrics& m);

}  // namespace rayfarm
