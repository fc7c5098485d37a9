#pragma once
// The benchmark scene: the synthetic plate at the paper's cloth ranks
// (Table 1: r_u = 30, r_a = 12, N ~ 8000 state nodes, 171 IRFs, ~3300 points).

#include "phasecast/core/package.h"

#include <filesystem>
#include <memory>

namespace phasecast::bench {

std::shared_ptr<const core::ScenePackage> cloth_ranks_scene();
// The same scene written once to a package file (for the server transport).
const std::filesystem::path& cloth_ranks_package_file();

}  // namespace phasecast::bench
