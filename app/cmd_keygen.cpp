// `rayfarm keygen -o NAME`: a CURVE key pair for a broker or a worker,
// NAME.key (secret, mode 0600) and NAME.pub (public; copy it to the other side).
#include <cstdio>
#include <memory>
#include <string>

#include "app/commands.h"
#include "protocol/curve_keys.h"

namespace rayfarm::cmd {

void add_keygen(CLI::App& app) {
  auto name = std::make_shared<std::string>();
  auto* sub = app.add_subcommand("keygen", "write a CURVE key pair NAME.key (secret) and NAME.pub (public)");
  sub->add_option("-o,--output", *name, "NAME: writes NAME.key and NAME.pub")->required();
  sub->callback([name] {
    const protocol::CurveKeyPair pair = protocol::write_key_files(*name);
    std::printf("%s.key: secret key (mode 0600; stays on this machine)\n%s.pub: public key %s\n", name->c_str(),
                name->c_str(), pair.public_key.c_str());
  });
}

}  // namespace rayfarm::cmd
