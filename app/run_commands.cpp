// run_commands (app/commands.h): the one command line of both programs.
#include <algorithm>
#include <cerrno>
#include <climits>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <string>
#include <vector>

#include "app/commands.h"
#include "tracer/log_text.h"

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

// The commands `app` has, for an error that found none: "render, spd, ...".
std::string command_names(const CLI::App& app) {
  std::string names;
  for (const CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; }))
    names += (names.empty() ? "" : ", ") + sub->get_name();
  return names;
}

// The option of `app`'s parsed command line named `name`, or null.
const CLI::Option* given_option(const CLI::App& app, const std::string& name) {
  for (const CLI::Option* option : app.get_options())
    if (option->get_name() == name) return option;
  for (const CLI::App* sub : app.get_subcommands())
    if (const CLI::Option* option = given_option(*sub, name)) return option;
  return nullptr;
}

// The forms of `option` the command line has: "-o" for `-o x.png` or
// `-ox.png`, "--output" for `--output x.png` or `--output=x.png`.
std::vector<std::string> typed_forms(const CLI::Option& option, int argc, char** argv) {
  std::vector<std::string> forms;
  for (const std::string& s : option.get_snames()) {
    const std::string form = "-" + s;
    for (int i = 1; i < argc; ++i)
      if (std::string(argv[i]).rfind(form, 0) == 0 && std::string(argv[i]).rfind("--", 0) != 0) {
        forms.push_back(form);
        break;
      }
  }
  for (const std::string& l : option.get_lnames()) {
    const std::string form = "--" + l;
    for (int i = 1; i < argc; ++i)
      if (argv[i] == form || std::string(argv[i]).rfind(form + "=", 0) == 0) {
        forms.push_back(form);
        break;
      }
  }
  return forms;
}

// `option` as the user wrote it: CLI11 names an option by its long form, so
// `-o nodir/x.png` was answered with "--output nodir/x.png: ...", an option
// the user never typed. An option typed one way is named that way; one not
// typed (or typed both ways) by all its forms, "-o/--output".
std::string typed_name(const CLI::Option& option, int argc, char** argv) {
  std::vector<std::string> forms = typed_forms(option, argc, argv);
  if (forms.size() != 1) {
    forms.clear();
    for (const std::string& s : option.get_snames()) forms.push_back("-" + s);
    for (const std::string& l : option.get_lnames()) forms.push_back("--" + l);
  }
  std::string name;
  for (const std::string& form : forms) name += (name.empty() ? "" : "/") + form;
  return name.empty() ? option.get_name() : name;  // a positional ("scene") has no dashed form
}

// `text` with the option it begins with ("--output: ...", "--output is
// required") named as the user typed it.
std::string naming_as_typed(const CLI::App& app, const std::string& text, int argc, char** argv) {
  const size_t end = text.find_first_of(": ");
  if (text.rfind("--", 0) != 0 || end == std::string::npos) return text;
  const CLI::Option* option = given_option(app, text.substr(0, end));
  return option ? typed_name(*option, argc, argv) + text.substr(end) : text;
}

// What `option` takes, in words, for "expected ...".
std::string expected_value(const CLI::Option* option) {
  if (!option) return "a value";
  if (option->get_expected_max() == 0) return "true or false (or no value)";  // a flag given =WORD
  const std::string type = option->get_type_name();
  if (type.rfind("FLOAT", 0) == 0 || type.rfind("NUMBER", 0) == 0) return "a number";
  return type.empty() ? "a value" : type;
}

// "unexpected argument WHAT (rayfarm COMMAND --help lists what it takes)".
std::string unexpected_argument_text(const CLI::App& app, const std::string& what) {
  const std::vector<CLI::App*> commands = app.get_subcommands();
  const std::string command = commands.empty() ? "rayfarm" : "rayfarm " + commands.front()->get_name();
  return "unexpected argument " + what + " (" + command + " --help lists what it takes)";
}

// The arguments the command given could not place, space-separated ("" if none).
std::string unparsed_arguments(const CLI::App& app) {
  std::string extras;
  for (const CLI::App* sub : app.get_subcommands())
    for (const std::string& arg : sub->remaining()) extras += (extras.empty() ? "" : " ") + arg;
  return extras;
}

// CLI::ExistingFile's "--config: File does not exist: nofile.json" in the
// words rayfarm's file reading uses, the path after its option (a positional,
// such as submit's scenes, is named by its path alone), or "" for any other
// error.
std::string existing_file_text(const std::string& text) {
  struct Wording {
    const char* cli11;
    const char* rayfarm;
  };
  static const Wording kWordings[] = {{": File does not exist: ", "cannot open (No such file or directory)"},
                                      {": File is actually a directory: ", "cannot read (Is a directory)"}};
  for (const Wording& w : kWordings) {
    const size_t at = text.find(w.cli11);
    if (at == std::string::npos) continue;
    const std::string name = text.substr(0, at), path = text.substr(at + std::strlen(w.cli11));
    return (name.rfind("-", 0) == 0 ? name + " " : "") + path + ": " + w.rayfarm;
  }
  return "";
}

// CLI11's parse errors in rayfarm's form (app/commands.h): one line, naming
// the option and what was found. CLI11 itself added "Run with --help for more
// information." on a second line, exited with codes of its own (104, 105,
// 106, ...), and said "A subcommand is required" of an unknown command,
// "--width: 1 required INT:INT in [1 - 65536] missing" of a value left out and
// "Could not convert: --cutoff = abc" of a word that is no number.
std::string parse_error_text(const CLI::App& app, const CLI::ParseError& error, int argc, char** argv) {
  std::string text = error.what();
  const std::string convert = "Could not convert: ";
  const std::string kReceived = " required but received ";
  if (app.get_subcommands().empty() && dynamic_cast<const CLI::RequiredError*>(&error)) {
    if (argc < 2) text = "no command given; give one of " + command_names(app) + " (or --help)";
    else text = "unknown command " + std::string(argv[1]) + "; the commands are " + command_names(app);
  } else if (dynamic_cast<const CLI::ArgumentMismatch*>(&error) && text.size() > 8 &&
             text.compare(text.size() - 8, 8, " missing") == 0 && text.find(": ") != std::string::npos) {
    text = text.substr(0, text.find(": ")) + ": expected a value, found none";
  } else if (dynamic_cast<const CLI::ConversionError*>(&error) && text.rfind(convert, 0) == 0 &&
             text.find(" = ") != std::string::npos) {
    const size_t equals = text.find(" = ");
    const std::string name = text.substr(convert.size(), equals - convert.size());
    text = name + ": expected " + expected_value(given_option(app, name)) + ", found " + text.substr(equals + 3);
  } else if (const size_t value = text.find(": Value "), range = text.find(" not in range ");
             dynamic_cast<const CLI::ValidationError*>(&error) && value != std::string::npos &&
             range != std::string::npos && range > value) {
    // CLI::Range's "--spp: Value 99999999999 not in range 1 to 65536".
    std::string bounds = text.substr(range + 14);
    if (const size_t to = bounds.find(" to "); to != std::string::npos) bounds.replace(to, 4, ", ");
    text = text.substr(0, value) + ": expected a value in [" + bounds + "], found " +
           text.substr(value + 8, range - value - 8);
  } else if (const std::string file_text = existing_file_text(text);
             dynamic_cast<const CLI::ValidationError*>(&error) && !file_text.empty()) {
    text = file_text;
  } else if (const size_t at_most = text.find(": At Most "), received = text.find(kReceived);
             dynamic_cast<const CLI::ArgumentMismatch*>(&error) && at_most != std::string::npos &&
             received != std::string::npos && received > at_most) {
    // CLI11's "--output: At Most 1 required but received 2" of `-o a.png --output b.png`.
    text = text.substr(0, at_most) + ": given " + text.substr(received + kReceived.size()) + " times; give it once";
  } else if (dynamic_cast<const CLI::ExtrasError*>(&error)) {
    text = unexpected_argument_text(app, text.substr(text.find(": ") + 2));
  } else if (const std::string extras = unparsed_arguments(app);
             dynamic_cast<const CLI::RequiredError*>(&error) && !extras.empty()) {
    // CLI11 checks what is required before what is left over: `render
    // --bogus` said "scene is required" of a scene it had not got to.
    text = unexpected_argument_text(app, extras);
  }
  std::replace(text.begin(), text.end(), '\n', ' ');
  return naming_as_typed(app, text, argc, argv);
}

// An error about a path given to an option, named by that option as other
// errors are: "--stats nodir/s.json: cannot write (...)", where the file
// code only knew "nodir/s.json: cannot write". Errors inside a file
// ("config.json:3: ...") and about positionals (the scene) are left as they are.
std::string naming_option(const CLI::App& app, const std::string& message, int argc, char** argv) {
  for (const CLI::Option* option : app.get_options()) {
    if (!option->nonpositional() || option->get_expected_max() == 0 || option->count() == 0) continue;
    for (const std::string& value : option->results())
      if (!value.empty() && message.rfind(value + ": ", 0) == 0)
        return typed_name(*option, argc, argv) + " " + message;
  }
  for (const CLI::App* sub : app.get_subcommands()) {
    const std::string named = naming_option(*sub, message, argc, argv);
    if (named != message) return named;
  }
  return message;
}

}  // namespace

int run_commands(int argc, char** argv, std::initializer_list<AddCommand> commands) {
  CLI::App app{"rayfarm: a distributed ray tracer for NFF scenes (Embree + ZeroMQ)"};
  app.require_subcommand(1);
  for (AddCommand add : commands) add(app);
  add_value_checks(app);
  // Errors quote paths and values as given, and a file name may hold a newline
  // or an ESC: escaped as log lines are (tracer/log_text.h), an error is one
  // line that cannot pass for another line, nor drive the terminal.
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == 0) return app.exit(e);  // --help
    std::fprintf(stderr, "rayfarm: %s\n", escape_control_characters(parse_error_text(app, e, argc, argv)).c_str());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "rayfarm: %s\n", escape_control_characters(naming_option(app, e.what(), argc, argv)).c_str());
    return 1;
  }
  return 0;
}

}  // namespace rayfarm::cmd
