// Placeholder until the render subcommand lands.
#include "app/commands.h"

namespace rayfarm::cmd {
void add_render(CLI::App& app) { app.add_subcommand("render", "(not built yet)"); }
}  // namespace rayfarm::cmd
