#pragma once
// The reduced discrete phase portrait's derived quantities (§2.3.2, §5.2):
// reduced velocities by finite differences (eq. 8), the default velocity
// weight beta of the distance metric (eq. 9), and the IRF reference cache.

#include "phasecast/core/eigen_types.h"

#include <cstdint>
#include <vector>

namespace phasecast::precompute {

// Eq. 8 per IRF: qdot^k = (q^{k+1} - q^k) / dt inside an IRF, and the
// backward difference (q^k - q^{k-1}) / dt at an IRF's last node (an orbit end
// or the step before a switch to the next IRF). A one-node IRF gets zero.
//   q_u        N x r_u reduced coordinates, IRFs stored as consecutive rows
//   irf_start, irf_length  n_irf, nodes irf_start[i] .. irf_start[i] + irf_length[i] - 1
MatrixXfR reduced_velocities(const MatrixXfR& q_u, const std::vector<std::int32_t>& irf_start,
                             const std::vector<std::int32_t>& irf_length, double dt);

// §2.3.2 default: beta = max_j ||q^j||^2 / max_j ||qdot^j||^2 (1 if all velocities vanish).
double default_beta(const MatrixXfR& q_u, const MatrixXfR& qdot_u);

// §5.2: for every node j and palette entry d, the IRF of entry d whose start
// node is nearest to node j under eq. 9, or -1 if entry d has no IRF.
// Exact search in blocks of nodes with one matrix product per block, so
// N = 20 000 nodes against thousands of IRF starts takes well under a second.
//   returns N x D
MatrixXiR nearest_irf_cache(const MatrixXfR& q_u, const MatrixXfR& qdot_u, double beta,
                            const std::vector<std::int32_t>& irf_start,
                            const std::vector<std::int32_t>& irf_palette, int palette_size);

}  // namespace phasecast::precompute
