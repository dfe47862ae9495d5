// Per-row cost profiles; see row_costs.h.
#include "replay/row_costs.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>

#include "protocol/json_fields.h"
#include "tracer/text_file.h"
#include "tracer/error.h"
#include "tracer/elapsed.h"
#include "tracer/renderer.h"

namespace rayfarm {
namespace {

constexpr const char* kFormat = "rayfarm-row-costs/1";

double finite_seconds(const nlohmann::json& v, const std::string& key_path) {
  if (!v.is_number() || !(v.get<double>() >= 0 && v.get<double>() <= kMaxReplaySeconds)) {
    char range[64];
    std::snprintf(range, sizeof range, "in [0, %g]", kMaxReplaySeconds);
    throw InputError(key_path + ": expected a finite number of seconds " + range + found_value(v));
  }
  return v.get<double>();
}

// The costs file: strict keys (JsonFields), the "rows" array checked by hand.
RowCosts costs_from_file_json(const nlohmann::json& j) {
  if (!j.is_object()) throw InputError("document: expected a JSON object");
  nlohmann::json rest = j;
  rest.erase("rows");
  JsonFields f(rest);
  const std::string format = f.string("format", 1, 64);
  if (format != kFormat) throw InputError("format: expected \"" + std::string(kFormat) + "\", got \"" + format + "\"");
  RowCosts c;
  f.read("scene", c.scene);
  f.read("source", c.source);
  f.read("width", c.width, 0, 65536);
  f.read("spp", c.spp, 0, 65536);
  double primitives = 0;
  f.read("primitives", primitives, 0, 1e12);
  c.primitives = static_cast<size_t>(primitives);
  f.read("init_s", c.init_s, 0, kMaxReplaySeconds);
  f.finish();
  auto rows = j.find("rows");
  if (rows == j.end()) throw InputError("rows: missing");
  if (!rows->is_array() || rows->empty() || rows->size() > 65536)
    throw InputError("rows: expected an array of 1..65536 seconds");
  for (size_t i = 0; i < rows->size(); ++i)
    c.rows.push_back(finite_seconds((*rows)[i], "rows[" + std::to_string(i) + "]"));
  return c;
}

const nlohmann::json& member(const nlohmann::json& obj, const char* key, const std::string& path) {
  if (!obj.is_object() || !obj.contains(key)) throw InputError(path + key + ": missing");
  return obj.at(key);
}

int member_int(const nlohmann::json& obj, const char* key, const std::string& path, int lo, int hi) {
  const nlohmann::json& v = member(obj, key, path);
  if (!v.is_number_integer() || v.get<int64_t>() < lo || v.get<int64_t>() > hi)
    throw InputError(path + key + ": expected an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]" +
                     found_value(v));
  return v.get<int>();
}

// A profile of no work has no speedup to predict: the replay printed a report
// whose every number was missing.
void refuse_no_work(const RowCosts& c, const std::string& path) {
  if (c.total() > 0) return;
  throw InputError(path + ": rows: all " + std::to_string(c.height()) +
                   " rows take 0 s (a profile needs some rendering time)");
}

// A costs file or a job record: a few MB at most (65536 rows; a record's tasks
// each a line). The limit turns /dev/zero or an endless pipe, which was read
// until memory ran out, into an error at once; a pipe from <(...) still reads.
constexpr size_t kMaxCostsBytes = 64u << 20;

nlohmann::json read_costs_json(const std::string& path) {
  return parse_json_text(read_text_file_within(path, kMaxCostsBytes, "64 MiB costs limit"), path);
}

}  // namespace

double RowCosts::total() const { return sum(0, height()); }

double RowCosts::sum(int y0, int y1) const {
  double s = 0;
  for (int y = y0; y < y1; ++y) s += rows[static_cast<size_t>(y)];
  return s;
}

RowCosts measure_row_costs(const Scene& scene, const RenderSettings& settings, const std::string& name,
                           int repeats, const std::function<void(int, int)>& progress) {
  using Clock = std::chrono::steady_clock;
  const auto t0 = Clock::now();
  Renderer renderer(scene, settings);
  RowCosts c;
  c.scene = name;
  c.source = "tracer";
  c.width = settings.width;
  c.spp = settings.spp;
  c.primitives = scene.primitive_count();
  c.init_s = seconds_since(t0);
  const int passes = std::max(1, repeats), h = settings.height;
  c.rows.assign(static_cast<size_t>(h), std::numeric_limits<double>::infinity());
  std::vector<float> rgb;
  for (int pass = 0; pass < passes; ++pass) {
    for (int y = 0; y < h; ++y) {
      const auto r0 = Clock::now();
      renderer.render_rows(y, y + 1, rgb);
      double& best = c.rows[static_cast<size_t>(y)];
      best = std::min(best, seconds_since(r0));
      if (progress) progress(pass * h + y + 1, passes * h);
    }
  }
  return c;
}

RowCosts row_costs_from_record(const nlohmann::json& record, const std::string& name) {
  const std::string at = name + ": ";
  const nlohmann::json& settings = member(record, "settings", at);
  const int height = member_int(settings, "height", at + "settings.", 1, 65536);
  RowCosts c;
  c.scene = record.contains("scene") && record["scene"].is_string() ? record["scene"].get<std::string>() : name;
  c.source = "job record";
  c.width = member_int(settings, "width", at + "settings.", 1, 65536);
  c.spp = member_int(settings, "spp", at + "settings.", 1, 65536);
  // The job's init: the fastest worker's parse + build (-1 = never ready).
  for (const nlohmann::json& w : record.value("workers", nlohmann::json::array())) {
    const double init = w.is_object() && w.contains("init_s") && w["init_s"].is_number() ? w["init_s"].get<double>() : -1;
    if (init >= 0 && (c.init_s == 0 || init < c.init_s)) c.init_s = init;
  }
  c.rows.assign(static_cast<size_t>(height), 0.0);
  // Pixels of each row covered by tasks: a row rendered in spans (x0, x1;
  // records before RFP/4 have whole rows only) costs the sum of its spans.
  std::vector<int> covered(static_cast<size_t>(height), 0);
  const nlohmann::json& tasks = member(record, "tasks", at);
  if (!tasks.is_array()) throw InputError(at + "tasks: expected an array");
  for (size_t i = 0; i < tasks.size(); ++i) {
    const std::string path = at + "tasks[" + std::to_string(i) + "].";
    const int y0 = member_int(tasks[i], "y0", path, 0, height - 1);
    const int y1 = member_int(tasks[i], "y1", path, y0 + 1, height);
    const bool has_x = tasks[i].is_object() && tasks[i].contains("x0");
    const int x0 = has_x ? member_int(tasks[i], "x0", path, 0, c.width - 1) : 0;
    const int x1 = has_x ? member_int(tasks[i], "x1", path, x0 + 1, c.width) : c.width;
    const double render_s = finite_seconds(member(tasks[i], "render_s", path), path + "render_s");
    for (int y = y0; y < y1; ++y) {
      int& px = covered[static_cast<size_t>(y)];
      px += x1 - x0;
      if (px > c.width) throw InputError(path + "y0: row " + std::to_string(y) + " is in two tasks");
      c.rows[static_cast<size_t>(y)] += render_s / (y1 - y0);
    }
  }
  const auto missing = std::find_if(covered.begin(), covered.end(), [&](int px) { return px != c.width; });
  if (missing != covered.end())
    throw InputError(at + "tasks: row " + std::to_string(missing - covered.begin()) + " is in no task (job unfinished?)");
  return c;
}

RowCosts load_row_costs(const std::string& path) {
  const nlohmann::json j = read_costs_json(path);
  RowCosts costs;
  if (j.is_object() && j.contains("tasks")) {
    costs = row_costs_from_record(j, path);
  } else {
    try {
      costs = costs_from_file_json(j);
    } catch (const InputError& e) {
      throw InputError(path + ": " + e.what());
    }
  }
  refuse_no_work(costs, path);
  return costs;
}

nlohmann::json row_costs_json(const RowCosts& c) {
  return {{"format", kFormat}, {"scene", c.scene},           {"source", c.source}, {"width", c.width},
          {"spp", c.spp},      {"primitives", c.primitives}, {"init_s", c.init_s}, {"rows", c.rows}};
}

RowCosts resample_rows(const RowCosts& c, int height) {
  if (height < 1 || c.rows.empty()) throw InputError("resample: need at least one row on both sides");
  RowCosts out = c;
  out.rows.assign(static_cast<size_t>(height), 0.0);
  // New row j covers old rows [j*k, (j+1)*k) with k = old/new, fractional at the ends.
  const double k = static_cast<double>(c.rows.size()) / height;
  for (int j = 0; j < height; ++j) {
    const double a = j * k, b = (j + 1) * k;
    for (int i = static_cast<int>(std::floor(a)); i < static_cast<int>(std::ceil(b)) && i < c.height(); ++i) {
      const double overlap = std::min(b, i + 1.0) - std::max(a, static_cast<double>(i));
      if (overlap > 0) out.rows[static_cast<size_t>(j)] += overlap * c.rows[static_cast<size_t>(i)];
    }
  }
  if (height != c.height()) out.source += ", resampled " + std::to_string(c.height()) + "->" + std::to_string(height) + " rows";
  return out;
}

RowCosts scale_to_total(const RowCosts& c, double total_s) {
  const double have = c.total();
  if (!(have > 0) || !(total_s > 0)) throw InputError("cannot scale a profile of total " + std::to_string(have) + " s");
  RowCosts out = c;
  const double f = total_s / have;
  for (double& r : out.rows) r *= f;
  out.init_s *= f;
  char buf[96];
  std::snprintf(buf, sizeof buf, ", scaled x%.4g to %.6g s", f, total_s);
  out.source += buf;
  return out;
}

}  // namespace rayfarm
