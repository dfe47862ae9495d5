// run_commands (app/commands.h): the one command line of both programs.
#include <algorithm>
#include <cerrno>
#include <climits>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>

#include "app/commands.h"

namespace rayfarm::cmd {
namespace {

// A whole number in decimal: an optional sign, then digits. Leading zeros
// are dropped, so that CLI11 does not read "010" as octal; anything else is
// refused naming what was found.
CLI::Validator decimal_whole_number() {
  return CLI::Validator(
      [](std::string& value) -> std::string {
        if (value.empty()) return "";  // the empty-value check says what is wrong
        const size_t sign = value[0] == '+' || value[0] == '-' ? 1 : 0;
        if (value.size() == sign || value.find_first_not_of("0123456789", sign) != std::string::npos)
          return "expected a whole number, found " + value;
        const size_t first = std::min(value.find_first_not_of('0', sign), value.size() - 1);
        value = value.substr(0, sign) + value.substr(first);
        return "";
      },
      "", "decimal");
}

// Checks every option and positional of `app` and its subcommands takes:
// - an empty value ('' from a variable that expanded to nothing, say) would
//   read as the option not given at all -- `--stats ''` wrote no statistics
//   and said nothing -- so it is refused;
// - CLI11 reads "-1" into an unsigned option as its largest value, and
//   anything beyond that as that value too, so both are refused there
//   (`--seed -1` was seed 18446744073709551615);
// - CLI11 reads a whole number in C's bases, so `--width 010` was 8 and
//   `--width 09` "not in range", and it said "--spp: Value 3.0 not in range
//   1 to 65536" of a 3.0 that is in range but not whole. Whole-number options
//   take decimal digits, leading zeros and all, and say what they found.
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
    const std::string type = option->get_type_name();
    // A transform runs before the option's own checks (CLI11's Range would say "not in range" first).
    if (type == "UINT" || type == "INT" || type.rfind("INT:", 0) == 0 || type.rfind("UINT:", 0) == 0)
      option->transform(decimal_whole_number());
    if (type == "UINT") option->check(unsigned_number);
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
