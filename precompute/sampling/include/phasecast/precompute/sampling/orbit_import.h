#pragma once
// Orbits made by other simulators (Maya, ABAQUS, Houdini, ...): a manifest
// lists the palette and the IRFs, each a folder of OBJ frames of one mesh
// topology, and becomes the same orbit store the engine writes
// (docs/simulator.md, "Importing external orbits").

#include "phasecast/precompute/sampling/orbit_store.h"

#include <filesystem>
#include <functional>

namespace phasecast::precompute {

// Reads the manifest (TOML) and every OBJ frame it names. Velocities are
// finite differences of the frames: backward within an IRF, forward at its
// first frame (zero for a one-frame IRF); support transforms are identity.
// Throws SceneError / ObjError with one line naming the file and field.
OrbitStore import_orbits(const std::filesystem::path& manifest,
                         const std::function<void(int, int)>& progress = {});

}  // namespace phasecast::precompute
