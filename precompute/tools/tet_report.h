#pragma once
// How far a run's tetrahedra were squashed: the least J = det F over every
// tet and frame, and how many frames hold an inverted tet (J <= 0). Printed
// by `simulate` for solids, so a material or step size that inverts elements
// is seen, not guessed (docs/simulator.md).

#include "phasecast/precompute/simulation/deformable_model.h"

#include <Eigen/Core>

#include <string>

namespace phasecast::precompute::tools {

struct TetSummary {
  int frames = 0;
  int frames_inverted = 0;  // frames with at least one tet at J <= 0
  double least_j = 1;       // the smallest det F seen
  int least_frame = -1, least_tet = -1;
};

// Over the rows of `positions` (frames x 3V, any rigid frame: J is invariant to it).
TetSummary summarize_tets(
    const DeformableModel& model,
    const Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>& positions);

// "tetrahedra: least J = det F 0.74 (frame 12, tet 301); 0 of 130 frames with an inverted tet"
std::string tet_line(const TetSummary& s, int tets);

}  // namespace phasecast::precompute::tools
