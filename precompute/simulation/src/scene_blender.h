#pragma once
// The parts of a scene file with [simulator] kind = "blender" (docs/scenes.md):
// the .blend holds bodies, materials, contact and solver settings.

#include "phasecast/precompute/simulation/scene.h"
#include "phasecast/precompute/simulation/scene_fields.h"

namespace phasecast::precompute::detail {

// [simulation]: frame_dt and settle only; Blender's own settings step the scene.
SimulationSettings read_blender_simulation(Fields sim, double default_settle);

// [simulator] and the model Blender describes: points, triangles, base
// colours, the drawn objects as meshes. Sections a .blend replaces are refused.
void read_blender_model(Fields& top, Scene& scene);

}  // namespace phasecast::precompute::detail
