// Finding a Python with matplotlib and running the study's plot script.
#include "study/plot_script.h"

#include <array>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>

namespace rayfarm {

namespace {

// Single-quotes a string for /bin/sh.
std::string shell_quote(const std::string& s) {
  std::string out = "'";
  for (char c : s) {
    if (c == '\'') {
      out += "'\\''";
    } else {
      out += c;
    }
  }
  return out + "'";
}

bool has_matplotlib(const std::string& python) {
  const std::string cmd = shell_quote(python) + " -c 'import matplotlib' >/dev/null 2>&1";
  return std::system(cmd.c_str()) == 0;
}

std::string trim(std::string s) {
  while (!s.empty() && (s.back() == '\n' || s.back() == '\r' || s.back() == ' ')) s.pop_back();
  return s;
}

}  // namespace

std::string find_plot_python() {
  std::vector<std::string> candidates;
  if (const char* env = std::getenv("RAYFARM_PYTHON"); env && *env) candidates.emplace_back(env);
  // A pyenv or venv python3 on PATH may lack matplotlib while Debian's has it.
  candidates.emplace_back("python3");
  candidates.emplace_back("/usr/bin/python3");
  for (const std::string& python : candidates) {
    if (has_matplotlib(python)) return python;
  }
  return "";
}

std::string find_plot_script(const std::string& explicit_path) {
  namespace fs = std::filesystem;
  if (!explicit_path.empty()) return fs::exists(explicit_path) ? explicit_path : "";
  std::vector<fs::path> candidates{fs::current_path() / "scripts" / "plot_study.py"};
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) candidates.push_back(exe.parent_path().parent_path() / "scripts" / "plot_study.py");
  for (const fs::path& p : candidates) {
    if (fs::exists(p, ec)) return p.string();
  }
  return "";
}

PlotOutcome run_plot_script(const std::string& script, const std::string& csv_path,
                            const std::string& out_dir) {
  PlotOutcome outcome;
  if (script.empty()) {
    outcome.note = "No plots: scripts/plot_study.py not found (run from the source tree or pass --plot-script).";
    return outcome;
  }
  const std::string python = find_plot_python();
  if (python.empty()) {
    outcome.note = "No plots: no python3 with matplotlib found (install python3-matplotlib or set RAYFARM_PYTHON).";
    return outcome;
  }
  const std::string cmd = shell_quote(python) + " " + shell_quote(script) + " " +
                          shell_quote(csv_path) + " " + shell_quote(out_dir);
  std::unique_ptr<FILE, int (*)(FILE*)> pipe(popen(cmd.c_str(), "r"), pclose);
  if (!pipe) {
    outcome.note = "No plots: could not start " + python;
    return outcome;
  }
  std::array<char, 512> line{};
  while (std::fgets(line.data(), line.size(), pipe.get())) {
    const std::string name = trim(line.data());
    if (!name.empty()) outcome.files.push_back(name);
  }
  const int status = pclose(pipe.release());
  if (status != 0) {
    outcome.note = "Plot script failed (exit status " + std::to_string(status) + "): " + cmd;
  } else {
    outcome.note = "Plots drawn by scripts/plot_study.py with " + python + ".";
  }
  return outcome;
}

}  // namespace rayfarm
