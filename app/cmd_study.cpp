// Placeholder until the study subcommand lands.
#include "app/commands.h"

namespace rayfarm::cmd {
void add_study(CLI::App& app) { app.add_subcommand("study", "(not built yet)"); }
}  // namespace rayfarm::cmd
