// phasecast-precompute run: sample -> reduce -> appearance in one command.

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
  ReduceStageOptions reduce;
  AppearanceChoices appearance;
};

}  // namespace

void add_run_command(CLI::App& app) {
  auto o = std::make_shared<Options>();
  CLI::App* cmd = app.add_subcommand(
      "run",
      "Build a scene package from a scene file: sample IRFs, reduce, then the appearance stage (resumable).");
  cmd->add_option("scene", o->scene, "scene file (.toml)")->required();
  cmd->add_option("-o,--output", o->output, "scene package to write (.h5)")->required();
  add_sample_options(cmd, o->sample);
  add_reduce_options(cmd, o->reduce);
  add_appearance_options(cmd, o->appearance);
  cmd->callback([o] {
    const auto scene = phasecast::precompute::load_scene_file(o->scene);
    // Bad appearance options fail before the sampling hours, not after.
    if (!o->appearance.skip) appearance_stage_options(scene, o->appearance);
    auto sample = o->sample;
    if (sample.work_dir.empty()) sample.work_dir = o->output + ".work";
    const std::filesystem::path orbits = sample.work_dir / "orbits.h5";
    check_save_transfers(o->appearance, {orbits, o->output});
    const auto sampled = run_sample_stage(scene, sample, orbits);
    if (sampled.writer) fmt::print("{}", sample_report_text(sampled));
    const auto reduced = run_reduce_stage(scene, o->reduce, o->appearance, orbits, o->output);
    if (reduced.writer) fmt::print("{}", reduce_report_text(reduced));
  });
}

}  // namespace phasecast::precompute::tools
