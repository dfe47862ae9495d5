// rayfarm: a distributed Whitted ray tracer. This file only dispatches to the
// subcommands and turns errors into one clear line and a non-zero exit code.
#include <cstdio>
#include <exception>

#include "app/commands.h"
#include "tracer/heap_pages.h"

int main(int argc, char** argv) {
  rayfarm::use_huge_heap_pages();
  CLI::App app{"rayfarm: a distributed ray tracer for NFF scenes (Embree + ZeroMQ)"};
  app.require_subcommand(1);
  rayfarm::cmd::add_render(app);
  rayfarm::cmd::add_spd(app);
  rayfarm::cmd::add_broker(app);
  rayfarm::cmd::add_worker(app);
  rayfarm::cmd::add_study(app);
  rayfarm::cmd::add_replay(app);
  rayfarm::cmd::add_client(app);
  rayfarm::cmd::add_keygen(app);
  rayfarm::cmd::add_calibrate(app);
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
