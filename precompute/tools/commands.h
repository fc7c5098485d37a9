#pragma once
// One registration function per phasecast-precompute subcommand, each in its
// own file, so parts of the pipeline are added without touching each other.

#include "phasecast/precompute/pipeline/scene_check.h"

#include <CLI/CLI.hpp>

namespace phasecast::precompute::tools {

void add_simulate_command(CLI::App& app);
void add_check_command(CLI::App& app);
void add_init_command(CLI::App& app);
void add_import_command(CLI::App& app);
void add_sample_command(CLI::App& app);
void add_reduce_command(CLI::App& app);
void add_run_command(CLI::App& app);
// `validate scene.toml package.h5`: playback against the full simulation (docs/validation.md).
void add_validate_command(CLI::App& app);
// check_scene with a progress bar per trial on stderr, and its report on stdout.
SceneCheck check_and_report(const Scene& scene, const core::ScenePackage* package,
                            const SceneCheckOptions& options);
// `transfer <mesh.obj> -o transfer.h5`: diffuse PRT of a static mesh (docs/transfer.md).
void add_transfer_command(CLI::App& app);
}  // namespace phasecast::precompute::tools
