// run_commands (app/commands.h): the one command line of both programs.
#include <cerrno>
#include <climits>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>

#include "app/commands.h"

namespace rayfarm::cmd {
namespace {

// Checks every option and positional of `app` and its subcommands takes:
// - an empty value ('' from a variable that expanded to nothing, say) would
//   read as the option not given at all -- `--stats ''` wrote no statistics
//   and said nothing -- so it is refused;
// - CLI11 reads "-1" into an unsigned option as its largest value, and
//   anything beyond that as that value too, so both are refused there
//   (`--seed -1` was seed 18446744073709551615).
void add_value_checks(CLI::App& app) {
  const CLI::Validator non_empty([](std::string& value) { return value.empty() ? std::string("empty value") : ""; },
                                 "", "non-empty");
  const CLI::Validator unsigned_number(
      [](std::string& value) -> std::string {
        if (value.rfind('-', 0) == 0) return "expected a number >= 0, found " + value;
        errno = 0;
        std::strtoull(value.c_str(), nullptr, 10);
        return errno == ERANGE ? "larger than " + std::to_string(ULLONG_MAX) + ": " + value : "";
      },
      "", "unsigned");
  for (CLI::Option* option : app.get_options()) {
    if (option->get_type_size_min() > 0) option->check(non_empty);
    if (option->get_type_name() == "UINT") option->check(unsigned_number);
  }
  for (CLI::App* sub : app.get_subcommands({})) add_value_checks(*sub);
}

}  // namespace

int run_commands(int argc, char** argv, std::initializer_list<AddCommand> commands) {
  CLI::App app{"rayfarm: a distributed ray tracer for NFF scenes (Embree + ZeroMQ)"};
  app.require_subcommand(1);
  for (AddCommand add : commands) add(app);
  add_value_checks(app);
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
