// Placeholder until the broker subcommand lands.
#include "app/commands.h"

namespace rayfarm::cmd {
void add_broker(CLI::App& app) { app.add_subcommand("broker", "(not built yet)"); }
}  // namespace rayfarm::cmd
