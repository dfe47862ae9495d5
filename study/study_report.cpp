// study.csv and study.md for an accuracy study.
#include "study/study_report.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "study/study_knobs.h"

namespace rayfarm {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Numbers for humans: "-" for NaN, "inf" for identical images.
std::string num(double v, const char* fmt = "%.4g") {
  if (std::isnan(v)) return "-";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  char buf[64];
  std::snprintf(buf, sizeof buf, fmt, v);
  return buf;
}

// Numbers for the CSV: full precision, empty for NaN, "inf" for +inf (Python's
// float() reads both).
std::string csv_num(double v) {
  if (std::isnan(v)) return "";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.9g", v);
  return buf;
}

// Text for the CSV: quoted when it holds a comma (presets do), as RFC 4180 says.
std::string csv_text(const std::string& s) {
  if (s.find_first_of(",\"") == std::string::npos) return s;
  std::string out = "\"";
  for (char c : s) out += c == '"' ? std::string("\"\"") : std::string(1, c);
  return out + "\"";
}

std::ofstream open_for_writing(const std::string& path) {
  std::ofstream out(path);
  if (!out) throw std::runtime_error(path + ": cannot open for writing");
  return out;
}

void finish(std::ofstream& out, const std::string& path) {
  out.flush();
  if (!out) throw std::runtime_error(path + ": write failed");
}

double rays_per_pixel(const StudyRow& row) {
  const double pixels = static_cast<double>(row.settings.width) * row.settings.height;
  return pixels > 0 ? static_cast<double>(row.rays.total()) / pixels : 0;
}

// Linear interpolation of y at x over points sorted by x; NaN outside.
double interpolate(const std::vector<std::pair<double, double>>& xy, double x) {
  for (size_t i = 0; i + 1 < xy.size(); ++i) {
    const auto [x0, y0] = xy[i];
    const auto [x1, y1] = xy[i + 1];
    const bool inside = (x >= std::min(x0, x1) && x <= std::max(x0, x1));
    if (!inside) continue;
    if (x1 == x0) return std::max(y0, y1);
    return y0 + (y1 - y0) * (x - x0) / (x1 - x0);
  }
  return kNaN;
}

std::vector<CostQuality> finite_sorted(std::vector<CostQuality> pts) {
  pts.erase(std::remove_if(pts.begin(), pts.end(),
                           [](const CostQuality& p) { return !(p.cost > 0) || !std::isfinite(p.psnr); }),
            pts.end());
  std::sort(pts.begin(), pts.end(), [](const CostQuality& a, const CostQuality& b) { return a.cost < b.cost; });
  return pts;
}

std::string yes(bool b) { return b ? "yes" : ""; }

// "spp 16, depth 5": the settings of a row as a reader names them, knob by knob.
std::string describe(const RenderSettings& s) {
  std::string out = "spp " + std::to_string(s.spp) + ", depth " + std::to_string(s.max_depth);
  if (s.adaptive_contrast > 0) out += ", adaptive " + num(s.adaptive_contrast);
  if (s.cutoff > 0) out += ", cutoff " + num(s.cutoff);
  if (s.robust_bvh) out += ", robust BVH";
  return out;
}

void row_cells(std::ostream& md, const StudyRow& row) {
  md << num(row.seconds, "%.3f") << " | " << row.rays.total() << " | " << num(rays_per_pixel(row), "%.1f") << " | "
     << num(row.diff.psnr, "%.2f") << " | " << num(row.diff.max_abs, "%.3f");
}

// One knob's table: its value, cost, error against the reference, the knob's
// error alone (when the sweep has an exact member) and the sweep's fronts.
void knob_table(std::ostream& md, const StudyResult& r, const KnobInfo& knob) {
  const auto rows = rows_of(r, knob.name);
  if (rows.empty()) return;
  const bool alone = !knob.exact.empty();
  md << "## " << knob.column << "\n\n" << knob.what;
  if (alone) md << " \"alone\" compares with " << knob.exact << " at the same sample positions: the knob's own error.";
  md << "\n\n| " << knob.column << " | time (s) | rays | rays/pixel | PSNR (dB) | max error |"
     << (alone ? " PSNR alone (dB) | max error alone |" : "") << " front (time) | front (rays) |\n"
     << "|---:|---:|---:|---:|---:|---:|" << (alone ? "---:|---:|" : "") << ":-:|:-:|\n";
  for (const StudyRow* row : rows) {
    md << "| " << row->value << (settings_key(row->settings) == settings_key(r.base) ? " (SPD)" : "") << " | ";
    row_cells(md, *row);
    if (alone) md << " | " << num(row->knob_diff.psnr, "%.2f") << " | " << num(row->knob_diff.max_abs, "%.3f");
    md << " | " << yes(row->front) << " | " << yes(row->front_rays) << " |\n";
  }
  md << "\n";
}

// Where the SPD's own setting sits, and the front over every knob's rows.
void front_table(std::ostream& md, const StudyResult& r) {
  md << "## Pareto front over all knobs (time)\n\n";
  if (const StudyRow* spd = base_row(r)) {
    const double uniform_seconds = cost_for_psnr(uniform_curve(r, Cost::kSeconds), spd->diff.psnr);
    md << "The SPD setting (" << describe(spd->settings) << "): " << num(spd->seconds, "%.3f") << " s, PSNR "
       << num(spd->diff.psnr, "%.2f") << " dB, max error " << num(spd->diff.max_abs, "%.3f") << "; "
       << (spd->front_all ? "on" : "not on") << " the front.";
    // The best front point no slower than the SPD setting says what it leaves on the table.
    const StudyRow* best = nullptr;
    for (const StudyRow& row : r.rows) {
      if (row.front_all && row.seconds <= spd->seconds && (!best || row.diff.psnr > best->diff.psnr)) best = &row;
    }
    if (best && best->diff.psnr > spd->diff.psnr) {
      md << " At no more time, " << best->sweep << " " << best->value << " (" << describe(best->settings)
         << ") gives " << num(best->diff.psnr, "%.2f") << " dB in " << num(best->seconds, "%.3f") << " s.";
    }
    if (!std::isnan(uniform_seconds)) {
      md << " Uniform sampling reaches its PSNR in " << num(uniform_seconds, "%.3f") << " s.";
    }
    md << "\n\n";
  }
  md << "| knob | value | settings | time (s) | rays | rays/pixel | PSNR (dB) | max error |\n"
     << "|---|---:|---|---:|---:|---:|---:|---:|\n";
  std::vector<const StudyRow*> front;
  for (const StudyRow& row : r.rows) {
    if (row.front_all && !row.reused) front.push_back(&row);
  }
  std::sort(front.begin(), front.end(), [](const StudyRow* a, const StudyRow* b) { return a->seconds < b->seconds; });
  for (const StudyRow* row : front) {
    md << "| " << row->sweep << " | " << row->value << " | " << describe(row->settings) << " | ";
    row_cells(md, *row);
    md << " |\n";
  }
  md << "\n";
}

void adaptive_table(std::ostream& md, const StudyResult& r) {
  const auto rows = rows_of(r, "adaptive");
  if (rows.empty()) return;
  const std::vector<CostQuality> by_time = uniform_curve(r, Cost::kSeconds);
  const std::vector<CostQuality> by_rays = uniform_curve(r, Cost::kRays);
  md << "### Adaptive against uniform sampling\n\n"
     << "The uniform spp sweep's PSNR, interpolated linearly in log cost, at the adaptive row's rays traced "
     << "(deterministic) and time (as noisy as the machine); \"-\" = outside the sweep's range.\n\n"
     << "| spp / contrast | eye rays / pixel | PSNR (dB) | uniform PSNR at equal rays | gain (dB) |"
     << " uniform PSNR at equal time | gain (dB) |\n"
     << "|---:|---:|---:|---:|---:|---:|---:|\n";
  for (const StudyRow* row : rows) {
    const double pixels = static_cast<double>(row->settings.width) * row->settings.height;
    const double at_rays = psnr_at_cost(by_rays, static_cast<double>(row->rays.total()));
    const double at_time = psnr_at_cost(by_time, row->seconds);
    md << "| " << row->value << " | " << num(row->rays.eye / pixels, "%.2f") << " | " << num(row->diff.psnr, "%.2f")
       << " | " << num(at_rays, "%.2f") << " | " << num(row->diff.psnr - at_rays, "%+.2f") << " | "
       << num(at_time, "%.2f") << " | " << num(row->diff.psnr - at_time, "%+.2f") << " |\n";
  }
  md << "\n";
}

}  // namespace

const std::vector<std::string>& study_csv_columns() {
  static const std::vector<std::string> columns{
      "scene", "sweep", "value", "spp", "max_depth", "adaptive_contrast", "cutoff", "robust_bvh", "width", "height",
      "seconds", "runs", "build_seconds", "rays_total", "eye_rays", "eye_hit_rays", "shadow_rays", "reflection_rays",
      "refraction_rays", "rays_per_pixel", "rmse", "psnr_db", "max_abs", "mean_abs", "knob_psnr_db",
      "knob_max_abs", "non_finite", "reused", "spd", "front", "front_rays", "front_all", "front_all_rays"};
  return columns;
}

void write_study_csv(const StudyResult& r, const std::string& path) {
  std::ofstream out = open_for_writing(path);
  const auto& columns = study_csv_columns();
  for (size_t i = 0; i < columns.size(); ++i) out << (i ? "," : "") << columns[i];
  out << "\n";
  const std::string base = settings_key(r.base);
  for (const StudyRow& row : r.rows) {
    const bool has_diff = row.sweep != "reference";
    const auto metric = [&](double v) { return has_diff ? csv_num(v) : std::string(); };
    const auto knob_metric = [&](double v) { return row.has_knob_diff ? csv_num(v) : std::string(); };
    const RenderSettings& s = row.settings;
    out << r.scene_name << "," << row.sweep << "," << csv_text(row.value) << "," << s.spp << "," << s.max_depth << ","
        << csv_num(s.adaptive_contrast) << "," << csv_num(s.cutoff) << "," << (s.robust_bvh ? 1 : 0) << ","
        << s.width << "," << s.height
        << "," << csv_num(row.seconds) << "," << row.runs << "," << csv_num(row.build_seconds) << ","
        << row.rays.total() << ","
        << row.rays.eye << "," << row.rays.eye_hit << "," << row.rays.shadow << "," << row.rays.reflection << ","
        << row.rays.refraction << "," << csv_num(rays_per_pixel(row)) << "," << metric(row.diff.rmse) << ","
        << metric(row.diff.psnr) << "," << metric(row.diff.max_abs) << "," << metric(row.diff.mean_abs) << ","
        << knob_metric(row.knob_diff.psnr) << "," << knob_metric(row.knob_diff.max_abs) << ","
        << row.non_finite << "," << (row.reused ? 1 : 0) << ","
        << (has_diff && settings_key(s) == base ? 1 : 0) << "," << (row.front ? 1 : 0) << ","
        << (row.front_rays ? 1 : 0) << "," << (row.front_all ? 1 : 0) << "," << (row.front_all_rays ? 1 : 0)
        << "\n";
  }
  finish(out, path);
}

void write_study_markdown(const StudyResult& r, const StudyOptions& o, const std::string& path,
                          const std::vector<std::string>& plots, const std::string& plot_note) {
  std::ostringstream md;
  const auto refs = rows_of(r, "reference");
  md << "# Accuracy and its price: " << r.scene_name << "\n\n"
     << "Image " << r.width << "x" << r.height << ". Reference: " << o.reference_spp << " spp at depth "
     << o.reference_depth << " (its own sampler seed, independent of the sweeps)";
  if (!refs.empty()) {
    md << ", " << num(refs.front()->seconds, "%.1f") << " s to render"
       << (r.reference_cached ? " (loaded from the reference cache)" : "");
  }
  md << ". Every sweep varies one knob from the SPD's own settings (" << describe(r.base) << "). Threads: "
     << (o.threads > 0 ? std::to_string(o.threads) : std::string("all")) << ".\n\n"
     << "Times are wall-clock render times (BVH build excluded), the fastest of at least " << o.repeats
     << " runs (more, up to 10, while a setting's runs add up to less than " << num(o.min_timed_seconds)
     << " s); on a shared machine read them as ratios within a table, not as absolute speed. Errors are over "
     << "display values (clamped to [0, 1]) against the reference; PSNR uses peak 1. A row is on a front when no "
     << "other row of the same table is at least as fast and at least as good, and better in one.\n\n";
  uint64_t bad = 0;
  for (const StudyRow& row : r.rows) bad += row.non_finite;
  md << "Non-finite samples over all renders (raw count from the tracer): " << bad << ".\n\n";
  front_table(md, r);
  for (const KnobInfo& knob : r.knobs) {
    knob_table(md, r, knob);
    if (knob.name == "adaptive") adaptive_table(md, r);
  }
  if (!r.images.empty()) {
    md << "## Images\n\n";
    for (const std::string& img : r.images) md << "[" << img << "](" << img << ") ";
    md << "\n\n";
  }
  md << "## Plots\n\n";
  if (!plot_note.empty()) md << plot_note << "\n\n";
  for (const std::string& p : plots) md << "![" << p << "](" << p << ")\n\n";

  std::ofstream out = open_for_writing(path);
  out << md.str();
  finish(out, path);
}

StudyFiles write_study(const StudyResult& result, const StudyOptions& options, bool plots,
                       const std::string& plot_script) {
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::create_directories(options.out_dir, ec);
  if (ec) throw std::runtime_error(options.out_dir + ": cannot create directory: " + ec.message());
  StudyFiles files;
  files.csv = (fs::path(options.out_dir) / "study.csv").string();
  files.markdown = (fs::path(options.out_dir) / "study.md").string();
  write_study_csv(result, files.csv);
  if (plots) {
    files.plots = run_plot_script(find_plot_script(plot_script), files.csv, options.out_dir);
  } else {
    files.plots.note = "Plots not requested (--no-plots).";
  }
  write_study_markdown(result, options, files.markdown, files.plots.files, files.plots.note);
  return files;
}

std::vector<CostQuality> uniform_curve(const StudyResult& result, Cost cost) {
  std::vector<CostQuality> pts;
  for (const StudyRow* row : rows_of(result, "spp")) {
    const double c = cost == Cost::kSeconds ? row->seconds : static_cast<double>(row->rays.total());
    pts.push_back({c, row->diff.psnr});
  }
  return pts;
}

double psnr_at_cost(std::vector<CostQuality> uniform, double cost) {
  uniform = finite_sorted(std::move(uniform));
  if (!(cost > 0)) return kNaN;
  std::vector<std::pair<double, double>> xy;
  for (const CostQuality& p : uniform) xy.emplace_back(std::log(p.cost), p.psnr);
  return interpolate(xy, std::log(cost));
}

double cost_for_psnr(std::vector<CostQuality> uniform, double psnr) {
  uniform = finite_sorted(std::move(uniform));
  if (!std::isfinite(psnr)) return kNaN;
  std::vector<std::pair<double, double>> xy;
  for (const CostQuality& p : uniform) xy.emplace_back(p.psnr, std::log(p.cost));
  const double log_c = interpolate(xy, psnr);
  return std::isnan(log_c) ? kNaN : std::exp(log_c);
}

}  // namespace rayfarm
