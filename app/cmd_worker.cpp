// Placeholder until the worker subcommand lands.
#include "app/commands.h"

namespace rayfarm::cmd {
void add_worker(CLI::App& app) { app.add_subcommand("worker", "(not built yet)"); }
}  // namespace rayfarm::cmd
