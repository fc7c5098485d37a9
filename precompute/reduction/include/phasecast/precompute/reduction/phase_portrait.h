#pragma once
// The reduced discrete phase portrait's derived quantities (§2.3.2, §5.2):
// the default velocity weight beta of the distance metric (eq. 9) and the IRF
// reference cache. Reduced velocities (eq. 8) are core::orbit_velocities.

#include "phasecast/core/eigen_types.h"
#include "phasecast/core/phase_space.h"

#include <array>
#include <cstdint>
#include <vector>

namespace phasecast::precompute {

// §2.3.2 default: beta = max_j ||q^j||^2 / max_j ||qdot^j||^2 (1 if all velocities vanish).
double default_beta(const MatrixXfR& q_u, const MatrixXfR& qdot_u);

// Starts within this share of the portrait's radius (the largest |[q, sqrt(beta) q̇]|)
// of the nearest one are one state for playback (measured in docs/sampling.md).
inline constexpr double kSameStartFraction = core::kSameStateFraction;

using SupportVelocity = std::array<double, 3>;

// §5.2: for every node j and palette entry d, the IRF of entry d to play from
// node j, or -1 if entry d has no IRF. An impulse is a change of the
// support's velocity (the paper's plant: I_D = {(-v0, 0), (+v0, 0)}), and the
// phase state (q_u, q̇_u) lies in the support's frame without that velocity:
// `stop` after a push left is the opposite kick of `stop` after a push right,
// from states eq. 9 may find close. So the candidates are the IRFs of entry d
// whose start moved the support at node j's velocity (`support_velocity`,
// per node: support_velocities below; empty means one velocity everywhere),
// or every IRF of d when none did. Of the candidates whose start is within kSameStartFraction
// of the portrait's radius of the nearest candidate start under eq. 9, the
// longest, then the nearest, then the one sampled first (lowest index). A
// later impulse can cut a long IRF short, but a short one ends the entry (its
// on_end) before the user meant it to, and every chain's first IRF starts at
// the one settled rest. Distances are exact under eq. 9 with each difference
// taken in double. A matrix product per block of nodes (in double) finds the
// candidates, and each start within its rounding of the least is measured
// again directly, so N = 20 000 nodes against thousands of IRF starts takes
// about a second.
//   returns N x D
MatrixXiR nearest_irf_cache(const MatrixXfR& q_u, const MatrixXfR& qdot_u, double beta,
                            const std::vector<std::int32_t>& irf_start,
                            const std::vector<std::int32_t>& irf_length,
                            const std::vector<std::int32_t>& irf_palette, int palette_size,
                            const std::vector<SupportVelocity>& support_velocity = {});

// The support's velocity (m/s, or rad/s about the axis) in the state of each
// node of an orbit store's IRFs: inside an IRF its entry's held velocity, and
// at its first node, the state its impulse finds, the held velocity of the IRF
// it continues (0 when it continues no stored IRF: from the settled rest, or
// after a directed chain's lead-in, which the store does not hold). `held[d]`
// is entry d's forcing (alpha_forcing; a jolt's pulse returns to rest).
std::vector<SupportVelocity> support_velocities(const std::vector<std::int32_t>& irf_start,
                                                const std::vector<std::int32_t>& irf_length,
                                                const std::vector<std::int32_t>& irf_palette,
                                                const std::vector<std::uint8_t>& continues,
                                                const std::vector<SupportVelocity>& held);

}  // namespace phasecast::precompute
