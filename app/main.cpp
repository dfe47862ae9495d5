// rayfarm: a distributed Whitted ray tracer. This program renders in its own
// process (`render`, `spd`, `study`) and hands every other command line --
// the farm's commands, `render --workers`, `replay`, `calibrate`, `--help` --
// to rayfarm-farm beside it, which has them all. Farm and service code pulls
// in ZeroMQ, HTTP and TLS libraries; loading them cost every render process
// some 350 page faults and their relocations (about 9 ms), which a one-shot
// render should not pay.
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>

#include "app/commands.h"
#include "tracer/executable_path.h"
#include "tracer/heap_pages.h"

namespace {

// Whether this program runs the command line itself: an in-process render
// (no --workers), an SPD scene, an accuracy study.
bool runs_here(int argc, char** argv) {
  if (argc < 2) return false;
  const std::string command = argv[1];
  if (command != "render" && command != "spd" && command != "study") return false;
  for (int i = 2; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--workers" || arg.rfind("--workers=", 0) == 0) return false;
  }
  return true;
}

// Replaces this process with rayfarm-farm, same arguments (and process id):
// the one beside this executable, else the first on PATH.
int exec_farm_program(char** argv) {
  const std::string self = rayfarm::executable_path();
  const std::string farm =
      self.empty() ? "rayfarm-farm" : (std::filesystem::path(self).parent_path() / "rayfarm-farm").string();
  if (self.empty())
    execvp(farm.c_str(), argv);
  else
    execv(farm.c_str(), argv);
  std::fprintf(stderr, "rayfarm: cannot run %s (it runs every command but render, spd and study): %s\n",
               farm.c_str(), std::strerror(errno));
  return 1;
}

}  // namespace

int main(int argc, char** argv) {
  if (!runs_here(argc, argv)) return exec_farm_program(argv);
  rayfarm::use_huge_heap_pages();
  namespace cmd = rayfarm::cmd;
  return cmd::run_commands(argc, argv, {[](CLI::App& app) { cmd::add_render(app, nullptr); }, cmd::add_spd,
                                        cmd::add_study});
}
