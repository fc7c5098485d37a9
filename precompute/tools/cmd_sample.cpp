// phasecast-precompute sample: random IRF chains obeying the palette rules (§3.4).

#include "commands.h"
#include "phasecast/precompute/pipeline/report_text.h"
#include "stage_options.h"

#include <fmt/format.h>

#include <memory>
#include <string>

namespace phasecast::precompute::tools {
namespace {

struct Options {
  std::string scene;
  std::string output;
  SampleStageOptions sample;
};

}  // namespace

void add_sample_command(CLI::App& app) {
  auto o = std::make_shared<Options>();
  CLI::App* cmd = app.add_subcommand(
      "sample", "Sample random IRF chains of a scene (checkpointed, resumable) into an orbit store (HDF5).");
  cmd->add_option("scene", o->scene, "scene file (.toml)")->required();
  cmd->add_option("-o,--output", o->output, "orbit store to write (.h5)")->required();
  add_sample_options(cmd, o->sample);
  cmd->callback([o] {
    const auto scene = phasecast::precompute::load_scene_file(o->scene);
    const auto report = run_sample_stage(scene, o->sample, o->output);
    if (report.writer) fmt::print("{}", sample_report_text(report));
  });
}

}  // namespace phasecast::precompute::tools
