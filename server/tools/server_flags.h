#pragma once
// phasecast-server's command line: the flags onto ServerOptions and the
// values main() turns into them.

#include "phasecast/server/server.h"

#include <CLI/CLI.hpp>

#include <string>
#include <vector>

namespace phasecast::server::tools {

struct ServerFlags {
  ServerOptions options;
  std::vector<std::string> packages;
  std::string record, replay, secret_key, allow_clients;
  double lambda = -1;  // < 0: the packages' own eq. 12 rate

  // The options with the values only main() knows are given.
  ServerOptions resolved() const;
};

void add_server_options(CLI::App& app, ServerFlags& flags);

}  // namespace phasecast::server::tools
