// phasecast-precompute: the offline pipeline (simulate, import, ...). Each
// subcommand registers itself; its callback runs the library code and throws
// on failure, reported here as one line. Under mpirun, sample, reduce and run
// spread their work over the ranks (docs/distributed.md); a rank that fails
// names itself and ends the whole run.

#include "commands.h"

#include "phasecast/core/command_line.h"
#include "phasecast/core/progress.h"
#include "phasecast/precompute/distributed/ranks.h"

#include <fmt/format.h>

#include <exception>

namespace {

// One line; in an MPI run it names the rank, and every rank stops with it.
int fail(const std::string& what, int code) {
  const phasecast::precompute::Ranks* ranks = nullptr;
  try {
    ranks = &phasecast::precompute::Ranks::world();
  } catch (const std::exception&) {  // a launcher but no MPI in this build: `what` says so
  }
  if (ranks && ranks->distributed()) {
    fmt::print(stderr, "phasecast-precompute: rank {} of {}: {}\n", ranks->rank(), ranks->size(), what);
    ranks->abort_all(code);
  }
  fmt::print(stderr, "phasecast-precompute: {}\n", what);
  return code;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    if (phasecast::precompute::Ranks::world().rank() > 0) phasecast::core::ProgressBar::mute_all();
  } catch (const std::exception& e) {
    return fail(e.what(), 1);
  }
  CLI::App app{
      "Phasecast offline precompute: simulate scenes, import external orbits, compute radiance "
      "transfer, build scene packages."};
  app.require_subcommand(1);
  namespace tools = phasecast::precompute::tools;
  tools::add_init_command(app);
  tools::add_simulate_command(app);
  tools::add_check_command(app);
  tools::add_import_command(app);
  tools::add_transfer_command(app);
  tools::add_sample_command(app);
  tools::add_reduce_command(app);
  tools::add_run_command(app);
  tools::add_validate_command(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::Success& e) {  // --help
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    // One line, as every other error; in an MPI run the other ranks would wait for this one, so
    // it names itself and ends them all.
    return fail(fmt::format("{} (see --help)", e.what()), phasecast::core::kUsageExitStatus);
  } catch (const std::exception& e) {
    return fail(e.what(), 1);
  }
  return 0;
}
