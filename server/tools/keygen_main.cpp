// phasecast-keygen: makes a CURVE key pair for a server or a client
// (docs/security.md): NAME.key (secret, mode 0600) stays with its owner,
// NAME.pub goes to the other side (a client's into the server's
// --allow-clients file, the server's to every client's --server-key).

#include "phasecast/core/curve_keys.h"

#include <fmt/format.h>
#include <zmq.h>
#include "phasecast/core/command_line.h"

#include <CLI/CLI.hpp>

#include <array>

int main(int argc, char** argv) {
  CLI::App app{
      "Make a CURVE key pair (NAME.key secret, NAME.pub public) for phasecast-server and its clients."};
  std::string name;
  app.add_option("name", name, "path stem of the two files, e.g. keys/server")->required();
  if (const auto status = phasecast::core::parse_command_line(app, argc, argv, "phasecast-keygen"))
    return *status;
  std::array<char, 41> pub{}, sec{};
  if (zmq_curve_keypair(pub.data(), sec.data()) != 0) {
    fmt::print(stderr,
               "phasecast-keygen: this libzmq has no CURVE support (expected one built with libsodium)\n");
    return 1;
  }
  try {
    phasecast::core::write_key_files(name, {pub.data(), sec.data()});
  } catch (const std::exception& e) {
    fmt::print(stderr, "phasecast-keygen: {}\n", e.what());
    return 1;
  }
  fmt::print("phasecast-keygen: wrote {}.key (secret, keep it) and {}.pub (public: {})\n", name, name,
             pub.data());
  return 0;
}
