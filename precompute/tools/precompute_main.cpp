// phasecast-precompute: the offline pipeline as subcommands (commands.h).
// Each subcommand's callback runs its work; failures surface here as one line.

#include "commands.h"

#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include <cstdio>
#include <exception>

int main(int argc, char** argv) {
  CLI::App app{"Phasecast offline precompute: radiance transfer and the scene package stages."};
  app.require_subcommand(1);
  phasecast::precompute::tools::add_transfer_command(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const std::exception& e) {
    fmt::print(stderr, "phasecast-precompute: {}\n", e.what());
    return 1;
  }
  return 0;
}
