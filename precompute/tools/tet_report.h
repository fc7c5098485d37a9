#pragma once
// The `tetrahedra:` line `simulate` prints for solids (tet_quality.h).

#include "phasecast/precompute/simulation/tet_quality.h"

#include <string>

namespace phasecast::precompute::tools {

// For example "tetrahedra: least J = det F 0.736 (frame 1, tet 4145 of 6484); 0 of 40 frames with an
// inverted tet (J <= 0)", or "... nothing to measure" without a tet or a frame.
std::string tet_line(const TetSummary& s, int tets);

}  // namespace phasecast::precompute::tools
