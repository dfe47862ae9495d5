// Running scripts/plot_study.py on a study's CSV. The plots are optional: when
// no Python with matplotlib or no script is found, the outcome says so in one
// line instead of failing the study.
#pragma once

#include <string>
#include <vector>

namespace rayfarm {

struct PlotOutcome {
  std::vector<std::string> files;  // PNG names inside out_dir, as the script printed them
  std::string note;                // why there are no plots, or which Python drew them
};

// The first of $RAYFARM_PYTHON, python3, /usr/bin/python3 that imports
// matplotlib; empty when none does.
std::string find_plot_python();

// The plot script: `explicit_path` if given, else scripts/plot_study.py under
// the working directory or next to the executable's parent directory (build/..).
// Empty when not found.
std::string find_plot_script(const std::string& explicit_path = "");

// Runs the script; never throws for a missing Python, reports it in `note`.
PlotOutcome run_plot_script(const std::string& script, const std::string& csv_path,
                            const std::string& out_dir);

}  // namespace rayfarm
