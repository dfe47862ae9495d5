// The command line of every `rayfarm` command as a user meets it: an error is
// one line, "rayfarm: ...", naming the option and what was found, with exit
// code 1 (app/commands.h); --help prints help and exits 0.
#include <doctest/doctest.h>

#include <string>

#include "tests/run_command.h"
#include "tests/test_files.h"
#include "tests/test_paths.h"

namespace rayfarm {
namespace {

std::string rayfarm_cmd(const std::string& args) { return test::rayfarm_exe() + " " + args; }

bool one_line(const std::string& output) {
  return !output.empty() && output.find('\n') == output.size() - 1;
}

const char* const kCommands[] = {"render", "spd",    "broker", "worker", "study",  "replay",
                                 "submit", "status", "cancel", "fetch",  "keygen", "calibrate"};

}  // namespace

TEST_CASE("command line: every command's parse errors are one line and exit code 1, its --help exit code 0") {
  // CLI11 added "Run with --help for more information." on a second line
  // and exited with codes of its own: 105, 106, 109, ...
  for (const std::string command : kCommands) {
    CAPTURE(command);
    const test::CommandResult bogus = test::run_command(rayfarm_cmd(command + " --bogus"));
    CHECK(bogus.exit_code == 1);
    CHECK(one_line(bogus.output));
    CHECK(bogus.output.rfind("rayfarm: ", 0) == 0);
    const test::CommandResult help = test::run_command(rayfarm_cmd(command + " --help"));
    CHECK(help.exit_code == 0);
    CHECK(help.output.find("Usage:") != std::string::npos);
  }
  const test::CommandResult help = test::run_command(rayfarm_cmd("--help"));
  CHECK(help.exit_code == 0);
  CHECK(help.output.find("Usage:") != std::string::npos);
}

TEST_CASE("command line: a parse error names the option, or the command, and what was found") {
  const std::string scene = test::spd_data("tetra-1");
  struct Case {
    std::string args;
    std::string output;
  } cases[] = {
      // Was "A subcommand is required" for both.
      {"", "rayfarm: no command given; give one of render, spd, broker, worker, study, replay, submit, status, "
           "cancel, fetch, keygen, calibrate (or --help)\n"},
      {"bogus", "rayfarm: unknown command bogus; the commands are render, spd, broker, worker, study, replay, "
                "submit, status, cancel, fetch, keygen, calibrate\n"},
      // Was "The following argument was not expected: --bogus", no command named.
      {"worker --bogus", "rayfarm: unexpected argument --bogus (rayfarm worker --help lists what it takes)\n"},
      {"spd tetra extra", "rayfarm: unexpected argument extra (rayfarm spd --help lists what it takes)\n"},
      // Was "scene is required": what is required was checked first.
      {"render --bogus", "rayfarm: unexpected argument --bogus (rayfarm render --help lists what it takes)\n"},
      {"study --bogus", "rayfarm: unexpected argument --bogus (rayfarm study --help lists what it takes)\n"},
      {"render", "rayfarm: scene is required\n"},
      // Was "--width: 1 required INT:INT in [1 - 65536] missing".
      {"render " + scene + " -o x.png --width", "rayfarm: --width: expected a value, found none\n"},
      {"render " + scene + " -o", "rayfarm: -o: expected a value, found none\n"},
      // Was "Could not convert: --cutoff = abc".
      {"render " + scene + " -o x.png --cutoff abc", "rayfarm: --cutoff: expected a number, found abc\n"},
      {"broker --reference-weight x1", "rayfarm: --reference-weight: expected a number, found x1\n"},
      {"broker --no-progress=maybe", "rayfarm: --no-progress: expected true or false (or no value), found maybe\n"},
      {"render " + scene, "rayfarm: -o/--output is required\n"},
      {"render " + scene + " -o x.png --width 0x10", "rayfarm: --width: expected a whole number, found 0x10\n"},
      // Was CLI11's "--spp: Value 99999999999 not in range 1 to 65536".
      {"render " + scene + " -o x.png --spp 99999999999",
       "rayfarm: --spp: expected a value in [1, 65536], found 99999999999\n"},
      {"render " + scene + " -o x.png --depth 0", "rayfarm: --depth: expected a value in [1, 64], found 0\n"},
  };
  for (const Case& c : cases) {
    CAPTURE(c.args);
    const test::CommandResult r = test::run_command(rayfarm_cmd(c.args));
    CHECK(r.exit_code == 1);
    CHECK(r.output == c.output);
  }
}

TEST_CASE("command line: an error about a path given to an option names the option") {
  // They began with the path alone: "nodir/s.json: cannot write (...)".
  const std::string scene = test::spd_data("tetra-1");
  struct Case {
    std::string args;
    std::string output;
  } cases[] = {
      {"render " + scene + " -o x.png --stats nodir/s.json",
       "rayfarm: --stats nodir/s.json: cannot write (no directory nodir)\n"},
      {"render " + scene + " -o nodir/x.png", "rayfarm: -o nodir/x.png: cannot write (no directory nodir)\n"},
      {"render " + scene + " -o x.png --workers 1 --farm-record nodir/r.json",
       "rayfarm: --farm-record nodir/r.json: cannot write (no directory nodir)\n"},
      {"broker " + scene + " -o x.png --config nodir/b.json",
       "rayfarm: --config nodir/b.json: cannot open (No such file or directory)\n"},
      {"spd tetra --output nodir/t.nff", "rayfarm: --output nodir/t.nff: cannot write (no directory nodir)\n"},
      // The scene is no option: its errors begin with its path, as do errors inside a file (FILE:LINE).
      {"render nodir/s.nff -o x.png", "rayfarm: nodir/s.nff: cannot open (No such file or directory)\n"},
  };
  for (const Case& c : cases) {
    CAPTURE(c.args);
    const test::CommandResult r = test::run_command(rayfarm_cmd(c.args));
    CHECK(r.exit_code == 1);
    CHECK(r.output == c.output);
  }
}

TEST_CASE("command line: control characters in an error's path are escaped, the error one line") {
  // Printed as given, "nodir/a<newline>rayfarm: wrote x.png" made two lines,
  // the second a forged one, and an ESC in a name drove the terminal.
  struct Case {
    std::string args;
    std::string output;
  } cases[] = {
      {"render 'nodir/a\nrayfarm: wrote x.png' -o x.png",
       "rayfarm: nodir/a\\nrayfarm: wrote x.png: cannot open (No such file or directory)\n"},
      {"render 'nodir/b\r\x1b[2K.nff' -o x.png",
       "rayfarm: nodir/b\\r\\x1b[2K.nff: cannot open (No such file or directory)\n"},
      // A positional's own check quotes it too.
      {"submit --broker http://127.0.0.1:9 'nodir/c\rd.nff'",
       "rayfarm: nodir/c\\rd.nff: cannot open (No such file or directory)\n"},
  };
  for (const Case& c : cases) {
    CAPTURE(c.args);
    const test::CommandResult r = test::run_command(rayfarm_cmd(c.args));
    CHECK(r.exit_code == 1);
    CHECK(one_line(r.output));
    CHECK(r.output == c.output);
  }
}

TEST_CASE("command line: text an error quotes from a file, or a scene's name, is escaped once, as its path is") {
  // The NFF token and the scene name were escaped where the error quoted them
  // and again with the whole message: "\\x1b" on the terminal, where the
  // path beside them read "\x1b".
  const std::string dir = test::scratch_dir("cli-escape-once").string();
  const std::string bad = test::write_file(dir + "/bad.nff", std::string(test::tiny_scene()) + "sph\x1b[2J 0 0 0 1\n");
  const test::CommandResult render = test::run_command(rayfarm_cmd("render " + bad + " -o " + dir + "/x.png"));
  CHECK(render.exit_code == 1);
  CHECK(render.output ==
        "rayfarm: " + bad + ":19: unknown keyword \"sph\\x1b[2J\" (expected b, v, l, f, c, s, p or pp)\n");
  const std::string named = test::write_file(dir + "/a\x1b[2Jb.nff", test::tiny_scene());
  const test::CommandResult submit =
      test::run_command(rayfarm_cmd("submit --broker http://127.0.0.1:9 '" + named + "'"));
  CHECK(submit.exit_code == 1);
  CHECK(submit.output == "rayfarm: scenes[0].name: expected no control characters (a scene's name is printed in logs "
                         "and terminals), found '" + dir + "/a\\x1b[2Jb.nff'\n");
}

TEST_CASE("command line: an option is named as it was typed, -o or --output, or by both forms if not typed") {
  // Errors named "--output" of a `-o nodir/x.png` the user typed.
  const std::string scene = test::spd_data("tetra-1");
  struct Case {
    std::string args;
    std::string output;
  } cases[] = {
      {"render " + scene + " -o nodir/x.png", "rayfarm: -o nodir/x.png: cannot write (no directory nodir)\n"},
      {"render " + scene + " --output nodir/x.png",
       "rayfarm: --output nodir/x.png: cannot write (no directory nodir)\n"},
      {"render " + scene + " --output=nodir/x.png",
       "rayfarm: --output nodir/x.png: cannot write (no directory nodir)\n"},
      {"render " + scene + " -onodir/x.png", "rayfarm: -o nodir/x.png: cannot write (no directory nodir)\n"},
      {"render " + scene + " -o ''", "rayfarm: -o: empty value\n"},
      {"render " + scene + " -o", "rayfarm: -o: expected a value, found none\n"},
      {"render " + scene + " --width 8", "rayfarm: -o/--output is required\n"},
      {"spd tetra -o nodir/t.nff", "rayfarm: -o nodir/t.nff: cannot write (no directory nodir)\n"},
      {"calibrate -o nodir/w.json", "rayfarm: -o nodir/w.json: cannot write (no directory nodir)\n"},
      // Typed both ways: both named.
      // Was CLI11's "At Most 1 required but received 2".
      {"render " + scene + " -o a.png --output b.png", "rayfarm: -o/--output: given 2 times; give it once\n"},
  };
  for (const Case& c : cases) {
    CAPTURE(c.args);
    const test::CommandResult r = test::run_command(rayfarm_cmd(c.args));
    CHECK(r.exit_code == 1);
    CHECK(r.output == c.output);
  }
}

TEST_CASE("command line: a file an option reads that is missing or a folder is named with the option") {
  // CLI11 said "--config: File does not exist: nofile.json" and
  // "--config: File is actually a directory: DIR".
  const std::string folder = test::source_dir() + "/tests";
  struct Case {
    std::string args;
    std::string output;
  } cases[] = {
      {"worker --config nofile.json", "rayfarm: --config nofile.json: cannot open (No such file or directory)\n"},
      {"worker --config " + folder, "rayfarm: --config " + folder + ": cannot read (Is a directory)\n"},
      {"worker --lab nolab.json", "rayfarm: --lab nolab.json: cannot open (No such file or directory)\n"},
      {"study " + test::spd_data("tetra-1") + " --plot-script noplot.py",
       "rayfarm: --plot-script noplot.py: cannot open (No such file or directory)\n"},
      // A positional is named by its path, as render's scene is.
      {"submit noscene.nff", "rayfarm: noscene.nff: cannot open (No such file or directory)\n"},
  };
  for (const Case& c : cases) {
    CAPTURE(c.args);
    const test::CommandResult r = test::run_command(rayfarm_cmd(c.args));
    CHECK(r.exit_code == 1);
    CHECK(r.output == c.output);
  }
}

TEST_CASE("command line: worker --name beside --lab is refused, not dropped for the lab's own names") {
  // Every machine of the lab kept its <type>-NN name, and the --name given
  // was ignored without a word. (`timeout`: a worker that starts serves on.)
  const test::CommandResult r = test::run_command(
      "timeout 10 " + rayfarm_cmd("worker --lab " + test::source_dir() +
                                  "/configs/labs/paper-lab.json --name render-07 --connect tcp://127.0.0.1:5555"));
  CHECK(r.exit_code == 1);
  CHECK(r.output == "rayfarm: --lab excludes --name\n");
}

TEST_CASE("command line: every command's sample count and scene size are named by their option when refused") {
  const std::string scene = test::spd_data("tetra-1");
  struct Case {
    std::string args;
    std::string output;
  } cases[] = {
      // Was "spp must be a perfect square ..." (calibrate) and accepted (replay).
      {"calibrate -o w.json --spp 3", "rayfarm: --spp: expected a perfect square k*k (1, 4, 9, 16, 25, ...), found 3\n"},
      {"replay --scene " + scene + " --lab configs/labs/paper-lab.json --spp 3",
       "rayfarm: --spp: expected a perfect square k*k (1, 4, 9, 16, 25, ...), found 3\n"},
      // Was accepted, and did nothing: the row costs were measured before.
      {"replay --costs costs.json --lab lab.json --spp 4",
       "rayfarm: --spp sets how --scene is measured; --costs brings row costs already measured\n"},
      // Was "spd tetra: size 0 out of range 1..10 (default 6)", no option named.
      {"spd tetra -s 0", "rayfarm: -s 0: expected a value in [1, 10] for spd tetra (default 6)\n"},
      {"spd rings --size 31", "rayfarm: --size 31: expected a value in [1, 30] for spd rings (default 7)\n"},
  };
  for (const Case& c : cases) {
    CAPTURE(c.args);
    const test::CommandResult r = test::run_command(rayfarm_cmd(c.args));
    CHECK(r.exit_code == 1);
    CHECK(r.output == c.output);
  }
}

}  // namespace rayfarm
