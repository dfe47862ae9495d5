// The `rayfarm` subcommands. Each file app/cmd_NAME.cpp only parses options and
// wires libraries together; the work lives in tracer/, spd/, broker/, worker/.
// Two programs share them (app/main.cpp): `rayfarm`, which renders in its own
// process and links no networking, and `rayfarm-farm`, which has them all.
#pragma once

#include <CLI/CLI.hpp>
#include <initializer_list>
#include <string>

#include "tracer/render_job.h"

namespace rayfarm::cmd {

using AddCommand = void (*)(CLI::App& app);
// Parses argv with the given subcommands and runs the chosen one; an error is
// one line on stderr and exit code 1.
int run_commands(int argc, char** argv, std::initializer_list<AddCommand> commands);

// Renders `job` on `workers` local worker processes of `threads` threads each
// (broker/farm_render_job.h), writing the farm's job record to `record_path`
// unless it is empty; null where the farm is not linked (`render --workers`
// then never reaches that program).
using LocalFarmRender = RenderReport (*)(const RenderJob& job, int workers, int threads,
                                         const RenderCallbacks& callbacks, const std::string& record_path);
void add_render(CLI::App& app, LocalFarmRender farm_render);
// `render` with the local farm: linked into rayfarm-farm only.
void add_render_with_farm(CLI::App& app);
void add_spd(CLI::App& app);
void add_broker(CLI::App& app);
void add_worker(CLI::App& app);
void add_study(CLI::App& app);
void add_replay(CLI::App& app);
void add_client(CLI::App& app);  // submit, status, cancel, fetch
void add_keygen(CLI::App& app);
void add_calibrate(CLI::App& app);

}  // namespace rayfarm::cmd
