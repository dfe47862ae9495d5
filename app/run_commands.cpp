// run_commands (app/commands.h): the one command line of both programs.
#include <cstdio>
#include <exception>

#include "app/commands.h"

namespace rayfarm::cmd {

int run_commands(int argc, char** argv, std::initializer_list<AddCommand> commands) {
  CLI::App app{"rayfarm: a distributed ray tracer for NFF scenes (Embree + ZeroMQ)"};
  app.require_subcommand(1);
  for (AddCommand add : commands) add(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "rayfarm: %s\n", e.what());
    return 1;
  }
  return 0;
}

}  // namespace rayfarm::cmd
