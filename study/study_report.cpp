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

// The table shared by the spp and depth sweeps: one knob column, then cost
// and error against the sweep's baseline.
void knob_table(std::ostream& md, const std::vector<const StudyRow*>& rows, const char* knob,
                int (*value)(const StudyRow&)) {
  md << "| " << knob << " | time (s) | rays | rays/pixel | RMSE | PSNR (dB) | max abs error |\n"
     << "|---:|---:|---:|---:|---:|---:|---:|\n";
  for (const StudyRow* row : rows) {
    md << "| " << value(*row) << " | " << num(row->seconds, "%.3f") << " | " << row->rays.total() << " | "
       << num(rays_per_pixel(*row), "%.1f") << " | " << num(row->diff.rmse) << " | "
       << num(row->diff.psnr, "%.2f") << " | " << num(row->diff.max_abs, "%.3f") << " |\n";
  }
  md << "\n";
}

void spp_table(std::ostream& md, const StudyResult& r, const StudyOptions& o) {
  md << "## Samples per pixel\n\n"
     << "Depth " << o.reference_depth << ", jittered k x k grid; error against the "
     << o.reference_spp << " spp reference.\n\n";
  knob_table(md, rows_of(r, "spp"), "spp", [](const StudyRow& row) { return row.settings.spp; });
}

void depth_table(std::ostream& md, const StudyResult& r, const StudyOptions& o) {
  const auto rows = rows_of(r, "depth");
  if (rows.empty()) return;
  md << "## Ray-tree depth\n\n"
     << o.depth_spp << " spp, eye ray = depth 1. Every depth uses the same sample positions, so the"
     << " error against the deepest render (" << rows.front()->baseline
     << ") is the truncation of the ray tree alone.\n\n";
  knob_table(md, rows, "max depth", [](const StudyRow& row) { return row.settings.max_depth; });
}

void adaptive_table(std::ostream& md, const StudyResult& r) {
  const auto rows = rows_of(r, "adaptive");
  if (rows.empty()) return;
  const std::vector<CostQuality> by_time = uniform_curve(r, Cost::kSeconds);
  const std::vector<CostQuality> by_rays = uniform_curve(r, Cost::kRays);
  md << "## Adaptive supersampling\n\n"
     << "Four corner cells of the k x k grid first; the rest only where their contrast "
     << "(max - min) / (max + min) exceeds the threshold in some channel. The comparisons "
     << "interpolate the uniform spp sweep's PSNR linearly in log cost, at equal rays traced "
     << "(deterministic) and at equal time (as noisy as the machine); \"-\" = outside the "
     << "sweep's range.\n\n"
     << "| spp | contrast | time (s) | eye rays / pixel | rays | PSNR (dB) | uniform PSNR at equal rays |"
     << " gain (dB) | uniform PSNR at equal time | gain (dB) |\n"
     << "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
  for (const StudyRow* row : rows) {
    const double pixels = static_cast<double>(row->settings.width) * row->settings.height;
    const double at_rays = psnr_at_cost(by_rays, static_cast<double>(row->rays.total()));
    const double at_time = psnr_at_cost(by_time, row->seconds);
    md << "| " << row->settings.spp << " | " << num(row->settings.adaptive_contrast) << " | "
       << num(row->seconds, "%.3f") << " | " << num(row->rays.eye / pixels, "%.2f") << " | "
       << row->rays.total() << " | " << num(row->diff.psnr, "%.2f") << " | " << num(at_rays, "%.2f")
       << " | " << num(row->diff.psnr - at_rays, "%+.2f") << " | " << num(at_time, "%.2f") << " | "
       << num(row->diff.psnr - at_time, "%+.2f") << " |\n";
  }
  md << "\n";
}

void cutoff_table(std::ostream& md, const StudyResult& r) {
  const auto rows = rows_of(r, "cutoff");
  if (rows.empty()) return;
  md << "## Ray-tree pruning (cutoff)\n\n"
     << "A reflection or refraction ray is not spawned when its weight (the product of the Ks / T "
     << "factors on its path) times the most one hit can shade falls below the cutoff. The full "
     << "tree is the uniform spp row with the same spp.\n\n"
     << "| cutoff | spp | time (s) | rays | rays / full tree | PSNR (dB) | full-tree PSNR (dB) |\n"
     << "|---:|---:|---:|---:|---:|---:|---:|\n";
  for (const StudyRow* row : rows) {
    const StudyRow* full = nullptr;
    for (const StudyRow* u : rows_of(r, "spp"))
      if (u->settings.spp == row->settings.spp) full = u;
    const double ratio = full ? static_cast<double>(row->rays.total()) / full->rays.total() : kNaN;
    md << "| " << num(row->settings.cutoff) << " | " << row->settings.spp << " | " << num(row->seconds, "%.3f")
       << " | " << row->rays.total() << " | " << num(ratio, "%.3f") << " | " << num(row->diff.psnr, "%.2f")
       << " | " << num(full ? full->diff.psnr : kNaN, "%.2f") << " |\n";
  }
  md << "\n";
}

void robust_table(std::ostream& md, const StudyResult& r) {
  const auto rows = rows_of(r, "robust");
  if (rows.empty()) return;
  md << "## Embree robust traversal (RTC_SCENE_FLAG_ROBUST)\n\n"
     << "| robust | spp | time (s) | rays | PSNR vs reference (dB) |\n"
     << "|---|---:|---:|---:|---:|\n";
  for (const StudyRow* row : rows) {
    md << "| " << (row->settings.robust_bvh ? "on" : "off") << " | " << row->settings.spp
       << " | " << num(row->seconds, "%.3f") << " | " << row->rays.total() << " | "
       << num(row->diff.psnr, "%.2f") << " |\n";
  }
  const ImageDiff& d = r.robust_on_vs_off;
  md << "\nOn against off, same samples: RMSE " << num(d.rmse) << ", max abs "
     << num(d.max_abs, "%.4f") << ", " << d.pixels_over << " pixels differ by more than 1/255.\n\n";
}

}  // namespace

const std::vector<std::string>& study_csv_columns() {
  static const std::vector<std::string> columns{
      "scene", "sweep", "spp", "max_depth", "adaptive_contrast", "cutoff", "robust_bvh", "width", "height",
      "seconds", "build_seconds", "rays_total", "eye_rays", "eye_hit_rays", "shadow_rays",
      "reflection_rays", "refraction_rays", "rays_per_pixel", "baseline", "rmse", "psnr_db",
      "max_abs", "mean_abs", "non_finite"};
  return columns;
}

void write_study_csv(const StudyResult& r, const std::string& path) {
  std::ofstream out = open_for_writing(path);
  const auto& columns = study_csv_columns();
  for (size_t i = 0; i < columns.size(); ++i) out << (i ? "," : "") << columns[i];
  out << "\n";
  for (const StudyRow& row : r.rows) {
    const bool has_diff = row.baseline != "none";
    const auto metric = [&](double v) { return has_diff ? csv_num(v) : std::string(); };
    const RenderSettings& s = row.settings;
    out << r.scene_name << "," << row.sweep << "," << s.spp << "," << s.max_depth << ","
        << csv_num(s.adaptive_contrast) << "," << csv_num(s.cutoff) << "," << (s.robust_bvh ? 1 : 0) << "," << s.width << ","
        << s.height << "," << csv_num(row.seconds) << "," << csv_num(row.build_seconds) << ","
        << row.rays.total() << "," << row.rays.eye << "," << row.rays.eye_hit << ","
        << row.rays.shadow << "," << row.rays.reflection << "," << row.rays.refraction << ","
        << csv_num(rays_per_pixel(row)) << "," << row.baseline << "," << metric(row.diff.rmse)
        << "," << metric(row.diff.psnr) << "," << metric(row.diff.max_abs) << ","
        << metric(row.diff.mean_abs) << "," << row.non_finite << "\n";
  }
  finish(out, path);
}

void write_study_markdown(const StudyResult& r, const StudyOptions& o, const std::string& path,
                          const std::vector<std::string>& plots, const std::string& plot_note) {
  std::ostringstream md;
  const auto refs = rows_of(r, "reference");
  md << "# Accuracy and its price: " << r.scene_name << "\n\n"
     << "Image " << r.width << "x" << r.height << " (a reduced size, to keep the converged "
     << "reference affordable); reference " << o.reference_spp << " spp at depth "
     << o.reference_depth << " (its own sampler seed, independent of the sweeps)";
  if (!refs.empty()) md << ", rendered in " << num(refs.front()->seconds, "%.2f") << " s";
  md << ". Threads: " << (o.threads > 0 ? std::to_string(o.threads) : std::string("all")) << ".\n\n"
     << "Times are wall-clock render times (BVH build excluded), the fastest of " << o.repeats
     << " run(s); on a shared machine read them as ratios within a table, not as absolute speed. Errors are over "
     << "display values (clamped to [0, 1]); PSNR uses peak 1.\n\n";
  size_t bad = 0;
  for (const StudyRow& row : r.rows) bad += row.non_finite;
  md << "Non-finite values over all renders: " << bad << ".\n\n";
  spp_table(md, r, o);
  depth_table(md, r, o);
  adaptive_table(md, r);
  cutoff_table(md, r);
  robust_table(md, r);
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
