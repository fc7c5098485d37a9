#pragma once
// Options and stages shared by the sample, reduce and run subcommands.

#include "phasecast/precompute/appearance/appearance_stage.h"
#include "phasecast/precompute/package/package_builder.h"
#include "phasecast/precompute/sampling/irf_sampler.h"

#include <CLI/CLI.hpp>

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace phasecast::precompute::tools {

struct SampleArgs {
  precompute::SamplingOptions sampling;
  std::string work_dir;  // empty: <output>.work
};

struct ReduceArgs {
  precompute::ReductionOptions reduction;
  precompute::PackageOptions package;
};

struct AppearanceArgs {
  precompute::AppearanceStageOptions stage;
  // Not given: the scene's [appearance] value, else the built-in default.
  std::optional<int> clusters, held_out, rays;
  std::optional<double> eps_a;
  std::string interpolant = "best";
  std::string weighting = "best";  // --transfer-weighting
  bool skip = false;               // --no-appearance: the package has no /appearance (r_a = 0)
  std::string save_transfers;  // --save-transfers: where every true transfer of the stage goes ("": nowhere)
};

// The stage's options for this scene: what the command line gave, else the
// scene's [appearance] defaults, else the built-in ones; the scene's albedo
// per point. Throws std::invalid_argument for a bad value.
precompute::AppearanceStageOptions appearance_stage_options(const precompute::Scene& scene,
                                                            const AppearanceArgs& args);

// --save-transfers is checked before any work: a file (not a folder) in an
// existing folder this user can write, none of `inputs_and_outputs` (the
// orbit store, the package), and the stage it saves from must run. Throws
// std::invalid_argument.
void check_save_transfers(const AppearanceArgs& args,
                          const std::vector<std::filesystem::path>& inputs_and_outputs);

void add_sample_options(CLI::App* cmd, SampleArgs& args);
void add_reduce_options(CLI::App* cmd, ReduceArgs& args);
void add_appearance_options(CLI::App* cmd, AppearanceArgs& args);

// Samples IRFs of the scene and writes the concatenated orbit store to `orbits`.
void run_sample_stage(const precompute::Scene& scene, SampleArgs args, const std::filesystem::path& orbits);

// Reduces the orbit store, runs the appearance stage on it (unless skipped)
// and writes the package; prints r_u, r_a, their errors and what the filter dropped.
void run_reduce_stage(const precompute::Scene& scene, const ReduceArgs& args,
                      const AppearanceArgs& appearance, const std::filesystem::path& orbits,
                      const std::filesystem::path& package);

}  // namespace phasecast::precompute::tools
