// phasecast-precompute reduce: model reduction of sampled orbits into a scene package (§2.3, §5.2).

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
  std::string orbits;
  std::string output;
  ReduceStageOptions reduce;
  AppearanceChoices appearance;
};

}  // namespace

void add_reduce_command(CLI::App& app) {
  auto o = std::make_shared<Options>();
  CLI::App* cmd = app.add_subcommand(
      "reduce",
      "Reduce sampled orbits (randomized SVD, phase portrait, IRF cache, appearance) into a scene package.");
  cmd->add_option("scene", o->scene, "scene file (.toml) the orbits were sampled from")->required();
  cmd->add_option("orbits", o->orbits, "orbit store (.h5) from 'sample' or 'simulate'")->required();
  cmd->add_option("-o,--output", o->output, "scene package to write (.h5)")->required();
  add_reduce_options(cmd, o->reduce);
  add_appearance_options(cmd, o->appearance);
  cmd->callback([o] {
    const auto scene = phasecast::precompute::load_scene_file(o->scene);
    const auto report = run_reduce_stage(scene, o->reduce, o->appearance, o->orbits, o->output);
    if (report.writer) fmt::print("{}", reduce_report_text(report));
  });
}

}  // namespace phasecast::precompute::tools
