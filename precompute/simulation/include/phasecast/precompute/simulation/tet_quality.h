#pragma once
// How far a run squashed a solid's tetrahedra: the least J = det F over every
// tet and frame, and how many frames hold an inverted tet (J <= 0), so that a
// material or step size that inverts elements is seen, not guessed
// (`simulate` prints it; docs/simulator.md).

#include "phasecast/precompute/simulation/deformable_model.h"

#include <Eigen/Core>

#include <limits>

namespace phasecast::precompute {

struct TetSummary {
  int frames = 0;
  int frames_inverted = 0;                                   // frames with at least one tet at J <= 0
  double least_j = std::numeric_limits<double>::infinity();  // infinity: no tet or no frame
  int least_frame = -1, least_tet = -1;
};

// Over the rows of `positions` (frames x 3V, in any rigid frame: J does not depend on it).
TetSummary summarize_tets(
    const DeformableModel& model,
    const Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>& positions);

}  // namespace phasecast::precompute
