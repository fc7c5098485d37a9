// phasecast-precompute import: orbits from an external simulator into an orbit store.

#include "commands.h"
#include "phasecast/core/progress.h"
#include "phasecast/precompute/distributed/ranks.h"
#include "phasecast/precompute/sampling/orbit_import.h"

#include <fmt/format.h>

#include <memory>
#include <string>

namespace phasecast::precompute::tools {
namespace {

struct ImportOptions {
  std::string manifest;
  std::string output;
};

void run_import(const ImportOptions& o) {
  using namespace phasecast::precompute;
  phasecast::core::ProgressBar bar("import");
  const OrbitStore store = import_orbits(o.manifest, [&](int done, int total) { bar.update(done, total); });
  bar.finish();
  write_orbit_store(store, o.output);
  fmt::print("wrote {} ({} frames, {} IRFs, {} vertices)\n", o.output, store.frames(), store.irf_start.size(),
             store.vertices());
}

}  // namespace

void add_import_command(CLI::App& app) {
  auto options = std::make_shared<ImportOptions>();
  CLI::App* cmd = app.add_subcommand(
      "import",
      "Import orbits from another simulator (a TOML manifest of IRFs, each a folder of OBJ frames).");
  cmd->add_option("manifest", options->manifest, "manifest (.toml), see docs/simulator.md")->required();
  cmd->add_option("-o,--output", options->output, "orbit store to write (.h5)")->required();
  cmd->callback([options] {
    Ranks::world().require_one_process("import");
    run_import(*options);
  });
}

}  // namespace phasecast::precompute::tools
