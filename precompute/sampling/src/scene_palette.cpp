#include "phasecast/precompute/sampling/scene_palette.h"

namespace phasecast::precompute {

PaletteArrays palette_arrays(const Scene& scene) {
  PaletteArrays a;
  const auto D = static_cast<Eigen::Index>(scene.palette.size());
  a.alpha_impulse.resize(D, 3);
  a.alpha_forcing.resize(D, 3);
  for (Eigen::Index d = 0; d < D; ++d) {
    const auto& e = scene.palette[static_cast<size_t>(d)];
    a.names.push_back(e.name);
    a.alpha_impulse.row(d) = e.alpha_impulse.cast<float>().transpose();
    a.alpha_forcing.row(d) = e.alpha_forcing.cast<float>().transpose();
    a.kinematics.push_back(entry_kinematics(scene, static_cast<int>(d)));
  }
  return a;
}

}  // namespace phasecast::precompute
