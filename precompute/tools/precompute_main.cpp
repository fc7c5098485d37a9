// phasecast-precompute: the offline pipeline (simulate, import, ...). Each
// subcommand registers itself; its callback runs the library code and throws
// on failure, reported here as one line.

#include "commands.h"

#include <fmt/format.h>

#include <exception>

int main(int argc, char** argv) {
  CLI::App app{
      "Phasecast offline precompute: simulate scenes, import external orbits, compute radiance "
      "transfer, build scene packages."};
  app.require_subcommand(1);
  namespace tools = phasecast::precompute::tools;
  tools::add_simulate_command(app);
  tools::add_import_command(app);
  tools::add_transfer_command(app);
  tools::add_sample_command(app);
  tools::add_reduce_command(app);
  tools::add_run_command(app);
  tools::add_validate_command(app);
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
