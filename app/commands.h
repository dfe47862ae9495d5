// The `rayfarm` subcommands. Each file app/cmd_NAME.cpp only parses options and
// wires libraries together; the work lives in tracer/, spd/, broker/, worker/.
#pragma once

#include <CLI/CLI.hpp>

namespace rayfarm::cmd {

void add_render(CLI::App& app);
void add_spd(CLI::App& app);
void add_broker(CLI::App& app);
void add_worker(CLI::App& app);
void add_study(CLI::App& app);
void add_replay(CLI::App& app);
void add_client(CLI::App& app);  // submit, status, cancel, fetch
void add_keygen(CLI::App& app);
void add_calibrate(CLI::App& app);

}  // namespace rayfarm::cmd
