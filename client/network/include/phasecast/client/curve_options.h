#pragma once
// --server-key and --client-key, the same on every client tool and the gateway
// (docs/security.md); `prefix` groups them in a tool's --help ("network: ").

#include <CLI/CLI.hpp>

#include <string>

namespace phasecast::client {

struct CurveKeyFiles {
  std::string server_key, client_key;
};

inline void add_curve_options(CLI::App& app, CurveKeyFiles& keys, const std::string& prefix = {}) {
  app.add_option("--server-key", keys.server_key,
                 prefix +
                     "CURVE: the server's public key file (NAME.pub); encrypts the connections and checks "
                     "the server's identity");
  app.add_option("--client-key", keys.client_key,
                 prefix +
                     "CURVE: this client's secret key file (NAME.key), for servers with an allow-list "
                     "(--allow-clients); without it a fresh key pair is used");
}

}  // namespace phasecast::client
