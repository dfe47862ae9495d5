// Placeholder until the spd subcommand lands.
#include "app/commands.h"

namespace rayfarm::cmd {
void add_spd(CLI::App& app) { app.add_subcommand("spd", "(not built yet)"); }
}  // namespace rayfarm::cmd
