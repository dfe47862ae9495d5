// Prometheus text format; see metrics.h. Reference: the exposition format spec,
// prometheus.io/docs/instrumenting/exposition_formats.
#include "status/metrics.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <utility>

namespace rayfarm {
namespace {

// Label values escape backslash, double quote and line feed.
std::string label_value(const std::string& v) {
  std::string out;
  for (char c : v) {
    if (c == '\\') out += "\\\\";
    else if (c == '"') out += "\\\"";
    else if (c == '\n') out += "\\n";
    else out += c;
  }
  return out;
}

// Integers as integers (counts, "le" bounds like 10), other values in the
// shortest form that reads back exactly; +Inf as Prometheus spells it.
std::string number(double v) {
  if (std::isinf(v)) return v > 0 ? "+Inf" : "-Inf";
  if (std::isnan(v)) return "NaN";
  char buf[32];
  if (v == std::floor(v) && std::fabs(v) < 1e15) {
    std::snprintf(buf, sizeof buf, "%.0f", v);
    return buf;
  }
  for (int precision = 1; precision <= 17; ++precision) {  // the shortest that reads back exactly
    std::snprintf(buf, sizeof buf, "%.*g", precision, v);
    if (std::strtod(buf, nullptr) == v) break;
  }
  return buf;
}

void header(std::string& out, const std::string& name, const char* type, const char* help) {
  out += "# HELP " + name + " " + help + "\n# TYPE " + name + " " + type + "\n";
}

template <class Map>
void labelled(std::string& out, const std::string& name, const char* label, const Map& values) {
  for (const auto& [key, value] : values)
    out += name + "{" + label + "=\"" + label_value(key) + "\"} " + number(static_cast<double>(value)) + "\n";
}

}  // namespace

Histogram::Histogram(std::vector<double> upper_bounds) : bounds(std::move(upper_bounds)), counts(bounds.size() + 1, 0) {
  assert(std::is_sorted(bounds.begin(), bounds.end()));
}

void Histogram::observe(double value) {
  const size_t bucket = static_cast<size_t>(std::lower_bound(bounds.begin(), bounds.end(), value) - bounds.begin());
  counts[bucket] += 1;
  sum += value;
  count += 1;
}

std::vector<double> round_trip_bounds() { return {0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1, 2.5, 5, 10, 30, 60, 300}; }

std::string format_metrics(const FarmMetrics& m) {
  std::string out;
  header(out, "rayfarm_jobs", "gauge", "Jobs known to the broker, by state.");
  labelled(out, "rayfarm_jobs", "state", m.jobs_by_state);
  header(out, "rayfarm_rows_done_total", "counter", "Rows accepted from workers since the broker started.");
  out += "rayfarm_rows_done_total " + number(static_cast<double>(m.rows_done)) + "\n";
  header(out, "rayfarm_rows_per_second", "gauge", "Rows accepted per second, recent average.");
  out += "rayfarm_rows_per_second " + number(m.rows_per_second) + "\n";
  header(out, "rayfarm_workers", "gauge", "Registered workers, by state.");
  labelled(out, "rayfarm_workers", "state", m.workers_by_state);
  header(out, "rayfarm_rejected_messages_total", "counter", "Messages from workers the broker dropped, by reason.");
  labelled(out, "rayfarm_rejected_messages_total", "reason", m.rejected_by_reason);

  const std::string rt = "rayfarm_task_round_trip_seconds";
  header(out, rt, "histogram", "Task dispatch to accepted result, seconds.");
  const Histogram& h = m.task_round_trip;
  uint64_t cumulative = 0;
  for (size_t i = 0; i <= h.bounds.size(); ++i) {
    cumulative += h.counts[i];
    const double le = i < h.bounds.size() ? h.bounds[i] : INFINITY;
    out += rt + "_bucket{le=\"" + number(le) + "\"} " + number(static_cast<double>(cumulative)) + "\n";
  }
  out += rt + "_sum " + number(h.sum) + "\n";
  out += rt + "_count " + number(static_cast<double>(h.count)) + "\n";
  return out;
}

}  // namespace rayfarm
