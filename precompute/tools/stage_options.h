#pragma once
// The command-line flags of the sample, reduce and run subcommands.

#include "phasecast/precompute/pipeline/stages.h"

#include <CLI/CLI.hpp>

namespace phasecast::precompute::tools {

void add_sample_options(CLI::App* cmd, SampleStageOptions& options);
void add_reduce_options(CLI::App* cmd, ReduceStageOptions& options);
void add_appearance_options(CLI::App* cmd, AppearanceChoices& choices);

}  // namespace phasecast::precompute::tools
