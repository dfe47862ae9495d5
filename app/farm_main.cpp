// rayfarm-farm: every rayfarm command, the farm's and the service's among
// them. Users run `rayfarm`, which renders in its own process and hands all
// other command lines to this program (app/main.cpp).
#include "app/commands.h"
#include "tracer/heap_pages.h"

int main(int argc, char** argv) {
  rayfarm::use_huge_heap_pages();
  namespace cmd = rayfarm::cmd;
  return cmd::run_commands(argc, argv,
                           {cmd::add_render_with_farm, cmd::add_spd, cmd::add_broker, cmd::add_worker, cmd::add_study,
                            cmd::add_replay, cmd::add_client, cmd::add_keygen, cmd::add_calibrate});
}
