#pragma once
// Exports an orbit as one OBJ file per frame in world coordinates (support
// transform applied), the deformable surface followed by the rigid obstacle
// boxes and prop meshes, and rod edges as OBJ lines, so any mesh viewer can
// play the sequence.

#include "phasecast/precompute/sampling/orbit_store.h"
#include "phasecast/precompute/simulation/deformable_model.h"
#include "phasecast/precompute/simulation/prop_mesh.h"

#include <filesystem>
#include <functional>
#include <vector>

namespace phasecast::precompute {

// Writes <dir>/frame_00000.obj ...; creates `dir`. Returns the number of files.
int write_obj_frames(const OrbitStore& store, const std::vector<BoxObstacle>& obstacles,
                     const std::vector<PropMesh>& meshes, const std::filesystem::path& dir,
                     const std::function<void(int, int)>& progress = {});

}  // namespace phasecast::precompute
