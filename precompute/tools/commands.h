#pragma once
// Subcommands of phasecast-precompute, one file each (cmd_<name>.cpp).

#include <CLI/CLI.hpp>

namespace phasecast::precompute::tools {

// `transfer <mesh.obj> -o transfer.h5`: diffuse PRT of a static mesh (docs/transfer.md).
void add_transfer_command(CLI::App& app);

}  // namespace phasecast::precompute::tools
