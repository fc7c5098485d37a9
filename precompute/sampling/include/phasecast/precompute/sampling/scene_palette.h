#pragma once
// The impulse palette of a scene in the array form that orbit stores and
// packages share (/palette/names, alpha_impulse, alpha_forcing, kinematics).

#include "phasecast/core/package.h"
#include "phasecast/precompute/simulation/scene.h"

#include <string>
#include <vector>

namespace phasecast::precompute {

struct PaletteArrays {
  std::vector<std::string> names;                   // D
  MatrixXfR alpha_impulse;                          // D x 3
  MatrixXfR alpha_forcing;                          // D x 3
  std::vector<core::SupportKinematics> kinematics;  // D, from entry_kinematics
};

PaletteArrays palette_arrays(const Scene& scene);

}  // namespace phasecast::precompute
