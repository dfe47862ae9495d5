// `rayfarm spd NAME [--size N] [-o FILE] [--list]`: write one of Haines' SPD
// scenes as NFF, to stdout or a file. Parses options and calls spd/generators.h.
#include <cerrno>
#include <cstring>
#include <fstream>
#include <iostream>
#include <memory>
#include <string>

#include "app/commands.h"
#include "spd/generators.h"
#include "tracer/error.h"
#include "tracer/interrupt_cleanup.h"
#include "tracer/output_file.h"

namespace rayfarm::cmd {
namespace {

struct SpdOptions {
  std::string name;
  int size = 0;
  bool size_given = false;  // otherwise the generator's default
  std::string size_text;    // as typed, so that an error names the option (run_commands.cpp)
  std::string output;
  bool list = false;
};

// Named like a file's error, with the reason: a full disk or a file-size limit
// was only "failed to write NFF output".
void generate_to_stdout(const std::string& name, int size) {
  errno = 0;
  try {
    spd::generate(name, size, std::cout);  // ends with a flush, which is checked
  } catch (const std::runtime_error&) {
    std::cout.setstate(std::ios::failbit);
  }
  if (!std::cout)
    throw InputError(std::string("spd: stdout: cannot write (") + (errno ? std::strerror(errno) : "write failed") +
                     ")");
}

void run_spd(const SpdOptions& opt) {
  if (opt.list) {
    std::cout << "SPD scenes (name, default size, allowed sizes):\n" << spd::generator_table();
    return;
  }
  if (opt.name.empty()) throw InputError("spd: missing scene NAME (try --list)");
  const spd::Generator& gen = spd::find_generator(opt.name);
  const int size = opt.size_given ? opt.size : gen.default_size;
  // Before creating the output file; a size given is named by its option.
  if (opt.size_given && (size < 1 || size > gen.max_size))
    throw InputError(opt.size_text + ": expected a value in [1, " + std::to_string(gen.max_size) + "] for spd " +
                     gen.name + " (default " + std::to_string(gen.default_size) + ")");
  spd::check_size(gen, size);
  if (opt.output.empty()) {
    generate_to_stdout(opt.name, size);
    return;
  }
  // Written beside it and renamed, like images: a large scene takes a while,
  // and a file cut short by a full disk or a kill still parses, as a scene
  // with primitives missing.
  check_output_path(opt.output);
  remove_temporaries_on_interrupt();  // nor a temporary left beside it by Ctrl-C
  write_atomically(opt.output, [&](const std::string& temp) {
    errno = 0;
    std::ofstream file(temp, std::ios::binary | std::ios::trunc);
    try {
      if (file) spd::generate(opt.name, size, file);
      file.close();
    } catch (const std::runtime_error&) {
      file.setstate(std::ios::failbit);
    }
    if (!file)
      throw InputError("spd: " + temp + ": cannot write (" + (errno ? std::strerror(errno) : "write failed") + ")");
  });
}

}  // namespace

void add_spd(CLI::App& app) {
  auto opt = std::make_shared<SpdOptions>();
  CLI::App* sub = app.add_subcommand("spd", "write an SPD scene (Haines' Standard Procedural Databases) as NFF");
  sub->footer("Scenes:\n" + spd::generator_table());
  sub->add_option("name", opt->name, "scene name (see the list above or --list)");
  CLI::Option* size = sub->add_option(
      "-s,--size", opt->size, "size factor (recursion depth or resolution); default: the SPD's");
  sub->add_option("-o,--output", opt->output, "output file (default: stdout)");
  sub->add_flag("--list", opt->list, "list the scenes with their default and maximum sizes");
  sub->callback([opt, size] {
    opt->size_given = size->count() > 0;
    if (opt->size_given) opt->size_text = size->results().front();
    run_spd(*opt);
  });
}

}  // namespace rayfarm::cmd
